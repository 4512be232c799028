#include "algo/fitting/face_fit.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

// The fit target's preparation: lifting image points with depth, normals, operator corrections.
namespace fb {

std::optional<Eigen::Vector3d> lift_depth(const Image<float>& depth, const PinholeIntrinsics& k,
                                          const Eigen::Vector2d& px, int radius_px, bool strict) {
  // Bilinear depth where the 2x2 neighbourhood is one surface (no rim or silhouette).
  const int x0 = static_cast<int>(std::floor(px.x())), y0 = static_cast<int>(std::floor(px.y()));
  if (depth.contains(x0, y0) && depth.contains(x0 + 1, y0 + 1)) {
    const float d00 = depth.at(x0, y0), d10 = depth.at(x0 + 1, y0), d01 = depth.at(x0, y0 + 1),
                d11 = depth.at(x0 + 1, y0 + 1);
    const float lo = std::min({d00, d10, d01, d11}), hi = std::max({d00, d10, d01, d11});
    if (lo > 0.0f && hi - lo < 3.0f) {
      const double fx = px.x() - x0, fy = px.y() - y0;
      const double z = (1 - fy) * ((1 - fx) * d00 + fx * d10) + fy * ((1 - fx) * d01 + fx * d11);
      return k.unproject(px.x(), px.y(), z);
    }
  }
  if (strict) return std::nullopt;
  const int cx = static_cast<int>(std::lround(px.x())), cy = static_cast<int>(std::lround(px.y()));
  std::vector<float> d;
  for (int y = cy - radius_px; y <= cy + radius_px; ++y)
    for (int x = cx - radius_px; x <= cx + radius_px; ++x)
      if (depth.contains(x, y) && depth.at(x, y) > 0.0f) d.push_back(depth.at(x, y));
  if (d.empty()) return std::nullopt;
  // At a rim: the lower quartile, not the median. Lid and lip points sit at the rim of the eye
  // and mouth openings, and the surface behind an opening must not win.
  std::nth_element(d.begin(), d.begin() + d.size() / 4, d.end());
  return k.unproject(px.x(), px.y(), d[d.size() / 4]);
}

std::optional<Eigen::Vector3d> lift_with_depth(const FitTarget& target, const Eigen::Vector2d& px,
                                               int radius_px, bool strict) {
  return lift_depth(target.depth_mm, target.intrinsics, px, radius_px, strict);
}

namespace {

// A detector draws the jaw line along what it sees: on a beard or hair that is the beard's
// outline, up to centimetres off the jaw. Such contour points are dropped; the skin's depth and
// the interior points place the jaw.
void drop_contour_on_hair(FitTarget& target) {
  if (target.skin.empty()) return;
  constexpr int kRadius = 5;
  for (int l = 0; l < kFitLandmarkCount; ++l) {
    FitLandmark& lm = target.landmarks[static_cast<std::size_t>(l)];
    if (!is_contour_landmark(l) || !lm.valid) continue;
    const int cx = static_cast<int>(std::lround(lm.pixel.x())),
              cy = static_cast<int>(std::lround(lm.pixel.y()));
    double sum = 0;
    int n = 0;
    for (int dy = -kRadius; dy <= kRadius; ++dy)
      for (int dx = -kRadius; dx <= kRadius; ++dx)
        if (dx * dx + dy * dy <= kRadius * kRadius && target.skin.contains(cx + dx, cy + dy) &&
            target.depth_mm.at(cx + dx, cy + dy) > 0) {
          sum += target.skin.at(cx + dx, cy + dy);
          ++n;
        }
    if (n > 0 && sum / n < 0.5) lm = FitLandmark{};
  }
}

}  // namespace

Result<void> prepare_fit_target(FitTarget& target) {
  const int w = target.depth_mm.width, h = target.depth_mm.height;
  if (target.depth_mm.empty() || w < 3 || h < 3) return fail("fit: the depth map is empty");
  if (target.intrinsics.fx <= 0 || target.intrinsics.fy <= 0)
    return fail("fit: the depth intrinsics are not set");
  // A pixel has a normal only inside one surface: its four neighbours have depth and no depth
  // jump (silhouette) crosses it. Given normals (e.g. a ray-cast view's) are kept only there:
  // the ray caster also gives one-sided normals on the rims of the view and of its holes, where
  // fused depth is least reliable (grazing rays, the edges of what the head turn observed), and
  // letting those rims into Epos moved the neutral fit on a side of the face (the worst of 5
  // synthetic subjects 1.42 -> 0.92 mm vertex error, mean 0.72 -> 0.62 mm).
  const auto& k = target.intrinsics;
  auto point = [&](int x, int y, Eigen::Vector3d& p) {
    const float d = target.depth_mm.at(x, y);
    if (!(d > 0.0f)) return false;
    p = k.unproject(x, y, d);
    return true;
  };
  const bool given = target.normals.width == w && target.normals.height == h;
  if (!given) target.normals.resize(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      Eigen::Vector3f& n = target.normals.at(x, y);
      Eigen::Vector3d c, l, r, u, d;
      if (x == 0 || y == 0 || x == w - 1 || y == h - 1 || !point(x, y, c) || !point(x - 1, y, l) ||
          !point(x + 1, y, r) || !point(x, y - 1, u) || !point(x, y + 1, d) ||
          std::abs(l.z() - r.z()) > 20.0 || std::abs(u.z() - d.z()) > 20.0) {
        n.setZero();
        continue;
      }
      if (given) continue;
      Eigen::Vector3d nn = (r - l).cross(d - u);
      if (nn.norm() <= 0) {
        n.setZero();
        continue;
      }
      nn.normalize();
      if (nn.z() > 0) nn = -nn;  // towards the camera
      n = nn.cast<float>();
    }
  if (!target.confidence.empty() && (target.confidence.width != w || target.confidence.height != h))
    return fail("fit: the depth confidence map is not the depth map's size");
  if (!target.skin.empty() && (target.skin.width != w || target.skin.height != h))
    return fail("fit: the skin map is not the depth map's size");
  drop_contour_on_hair(target);
  int valid = 0;
  for (const auto& lm : target.landmarks) valid += lm.valid;
  if (valid == 0) return fail("fit: no face landmarks (no face found in the image)");
  int interior = 0;
  for (int l = 17; l < kFitLandmarkCount; ++l) {
    const FitLandmark& lm = target.landmarks[static_cast<std::size_t>(l)];
    interior += lm.valid && lm.point.has_value();
  }
  if (interior < 6)
    return fail("fit: only " + std::to_string(interior) +
                " interior landmarks have depth; the face region of the depth map is missing");
  return success();
}

Result<void> apply_corrections(FitTarget& target, std::span<const LandmarkCorrection> corrections) {
  for (const auto& c : corrections) {
    if (c.index < 0 || c.index >= kFitLandmarkCount)
      return fail("landmark correction: index " + std::to_string(c.index) + " is not in 0..67");
    FitLandmark& lm = target.landmarks[static_cast<std::size_t>(c.index)];
    if (c.remove) {
      lm = FitLandmark{};
      continue;
    }
    if (!c.pixel.allFinite()) return fail("landmark correction: pixel is not finite");
    lm.valid = true;
    lm.pixel = c.pixel;
    lm.point.reset();
    if (!is_contour_landmark(c.index)) lm.point = lift_with_depth(target, c.pixel, 2, true);
  }
  return success();
}

}  // namespace fb
