#include "algo/landmarks/skin_map.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "algo/core/polygon.hpp"

namespace fb {
namespace {

struct Chroma {
  double r = 0, g = 0, sum = 0;
  bool clipped = false;
};

// Mean colour of the 3x3 colour pixels around (x, y): the colour noise (a few levels) would
// otherwise move a shadowed pixel's chromaticity by as much as skin differs from hair.
bool sample(const ColorImage& c, int x, int y, Chroma& out) {
  double r = 0, g = 0, b = 0;
  int n = 0;
  bool clipped = false;
  for (int dy = -1; dy <= 1; ++dy)
    for (int dx = -1; dx <= 1; ++dx) {
      if (!c.contains(x + dx, y + dy)) continue;
      const Rgb8& p = c.at(x + dx, y + dy);
      r += p.r;
      g += p.g;
      b += p.b;
      clipped |= std::max({p.r, p.g, p.b}) >= 250;
      ++n;
    }
  if (n == 0) return false;
  const double sum = (r + g + b) / n;
  out.sum = sum;
  out.clipped = clipped;
  out.r = sum > 0 ? r / n / sum : 0;
  out.g = sum > 0 ? g / n / sum : 0;
  return true;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

struct SkinModel {
  double r = 0, g = 0, sr = 0, sg = 0, sum = 0;
  int samples = 0;
};

// The skin sample: disks on both cheekbones (between the jaw, the nose's base and the lower
// eyelid, above any beard) and on the nose's bridge (below the brows, inside any hairline).
SkinModel learn_skin(const ColorImage& color, std::span<const Eigen::Vector2d> lm,
                     const SkinMapOptions& o) {
  auto at = [&](int i) { return lm[static_cast<std::size_t>(i)]; };
  const std::array<Eigen::Vector2d, 4> centres = {(at(1) + at(31) + at(41)) / 3.0,
                                                  (at(15) + at(35) + at(46)) / 3.0, at(28), at(29)};
  const double radius = std::max(2.0, 0.07 * (at(36) - at(45)).norm());
  std::vector<double> rs, gs, sums;
  for (const Eigen::Vector2d& c : centres) {
    const int r = static_cast<int>(std::ceil(radius));
    for (int dy = -r; dy <= r; ++dy)
      for (int dx = -r; dx <= r; ++dx) {
        if (dx * dx + dy * dy > radius * radius) continue;
        Chroma s;
        const int x = static_cast<int>(std::lround(c.x())) + dx,
                  y = static_cast<int>(std::lround(c.y())) + dy;
        if (!color.contains(x, y) || !sample(color, x, y, s) || s.clipped || s.sum < 30) continue;
        rs.push_back(s.r);
        gs.push_back(s.g);
        sums.push_back(s.sum);
      }
  }
  SkinModel m;
  m.samples = static_cast<int>(rs.size());
  if (rs.empty()) return m;
  m.r = median(rs);
  m.g = median(gs);
  m.sum = median(sums);
  std::vector<double> dr(rs.size()), dg(gs.size());
  for (std::size_t i = 0; i < rs.size(); ++i) {
    dr[i] = std::abs(rs[i] - m.r);
    dg[i] = std::abs(gs[i] - m.g);
  }
  m.sr = std::max(o.chroma_floor, 1.4826 * median(dr));
  m.sg = std::max(o.chroma_floor, 1.4826 * median(dg));
  return m;
}

// The eyes, the lips and the brows are not skin-coloured, but their depth is the surface the
// model describes (they are not volumes in front of it): polygons around them, grown from their
// centres, in colour pixels.
struct FeatureMask {
  std::vector<std::vector<Eigen::Vector2d>> polygons;

  bool contains(double x, double y) const {
    for (const auto& p : polygons)
      if (inside_polygon(p, x, y)) return true;
    return false;
  }
};

FeatureMask feature_mask(std::span<const Eigen::Vector2d> lm) {
  FeatureMask m;
  auto grown = [&](int first, int last, double scale) {
    std::vector<Eigen::Vector2d> p(lm.begin() + first, lm.begin() + last + 1);
    Eigen::Vector2d c = Eigen::Vector2d::Zero();
    for (const auto& q : p) c += q;
    c /= static_cast<double>(p.size());
    for (auto& q : p) q = c + scale * (q - c);
    m.polygons.push_back(std::move(p));
  };
  grown(36, 41, 1.6);  // eyes (the lids' rims)
  grown(42, 47, 1.6);
  grown(48, 59, 1.25);  // lips
  // Brows: the brow line moved up and down by a fraction of the eye span.
  const double band = 0.06 * (lm[36] - lm[45]).norm();
  for (int first : {17, 22}) {
    std::vector<Eigen::Vector2d> p;
    for (int i = first; i < first + 5; ++i) p.push_back(lm[i] - Eigen::Vector2d(0, band));
    for (int i = first + 4; i >= first; --i) p.push_back(lm[i] + Eigen::Vector2d(0, band));
    m.polygons.push_back(std::move(p));
  }
  return m;
}

// 1 inside `limit`, falling linearly to 0 at `limit + soft`.
double ramp(double value, double limit, double soft) {
  return std::clamp(1.0 - (value - limit) / soft, 0.0, 1.0);
}

double skin_weight(const Chroma& s, const SkinModel& m, const SkinMapOptions& o) {
  if (s.clipped) return 1.0;  // a highlight: hair does not clip, skin under a key light does
  if (s.sum <= 0) return 0.0;
  const double dc = std::hypot((s.r - m.r) / m.sr, (s.g - m.g) / m.sg);
  const double darker = std::log(m.sum / s.sum);
  return std::min(ramp(dc, o.chroma_sigmas, o.soft_sigmas),
                  ramp(darker, std::log(o.darker_factor), std::log(o.soft_factor)));
}

void median_filter(const Image<float>& depth, int radius, Image<float>& map) {
  if (radius <= 0) return;
  const Image<float> in = map;
  std::vector<float> window;
  for (int y = 0; y < map.height; ++y)
    for (int x = 0; x < map.width; ++x) {
      if (depth.at(x, y) <= 0) continue;
      window.clear();
      for (int dy = -radius; dy <= radius; ++dy)
        for (int dx = -radius; dx <= radius; ++dx)
          if (map.contains(x + dx, y + dy) && depth.at(x + dx, y + dy) > 0)
            window.push_back(in.at(x + dx, y + dy));
      const auto mid = window.begin() + static_cast<std::ptrdiff_t>(window.size() / 2);
      std::nth_element(window.begin(), mid, window.end());
      map.at(x, y) = *mid;
    }
}

// Skin within `radius` of a region of hair or beard takes the region's least weight. A region
// is what a 7x7 window that is mostly under 0.5 covers (an opening): the thin dark rims of
// shadows (the jaw's underside, the head's outline) and the nostrils grow no margin.
void hair_margin(const Image<float>& depth, int radius, Image<float>& map) {
  if (radius <= 0) return;
  constexpr int kHalf = 3, kLeast = 30;  // of 49
  const Image<float> in = map;
  auto low = [&](int x, int y) {
    return in.contains(x, y) && depth.at(x, y) > 0 && in.at(x, y) < 0.5f;
  };
  Image<std::uint8_t> core, region;
  core.resize(map.width, map.height);
  region.resize(map.width, map.height);
  for (int y = 0; y < map.height; ++y)
    for (int x = 0; x < map.width; ++x) {
      if (!low(x, y)) continue;
      int n = 0;
      for (int dy = -kHalf; dy <= kHalf; ++dy)
        for (int dx = -kHalf; dx <= kHalf; ++dx) n += low(x + dx, y + dy);
      core.at(x, y) = n >= kLeast;
    }
  for (int y = 0; y < map.height; ++y)
    for (int x = 0; x < map.width; ++x) {
      if (!low(x, y)) continue;
      for (int dy = -kHalf; dy <= kHalf && !region.at(x, y); ++dy)
        for (int dx = -kHalf; dx <= kHalf && !region.at(x, y); ++dx)
          region.at(x, y) = core.contains(x + dx, y + dy) && core.at(x + dx, y + dy);
    }
  for (int y = 0; y < map.height; ++y)
    for (int x = 0; x < map.width; ++x) {
      if (depth.at(x, y) <= 0) continue;
      float least = in.at(x, y);
      for (int dy = -radius; dy <= radius; ++dy)
        for (int dx = -radius; dx <= radius; ++dx)
          if (region.contains(x + dx, y + dy) && region.at(x + dx, y + dy))
            least = std::min(least, in.at(x + dx, y + dy));
      map.at(x, y) = least;
    }
}

}  // namespace

Result<Image<float>> skin_map(const Image<float>& depth_mm, const ColorImage& color,
                              const KinectRegistration& registration,
                              std::span<const Eigen::Vector2d> color_landmarks,
                              const SkinMapOptions& options, SkinMapStats* stats) {
  if (color_landmarks.size() != 68)
    return fail("skin map: needs the 68 colour landmarks, got " +
                std::to_string(color_landmarks.size()));
  if (color.empty() || depth_mm.empty()) return fail("skin map: no colour or no depth image");
  const SkinModel model = learn_skin(color, color_landmarks, options);
  if (model.samples < 20)
    return fail("skin map: only " + std::to_string(model.samples) +
                " skin pixels between the landmarks (is the face inside the colour image?)");
  const FeatureMask features = feature_mask(color_landmarks);
  Image<float> map;
  map.resize(depth_mm.width, depth_mm.height);
  int with_depth = 0, skin = 0;
  for (int y = 0; y < depth_mm.height; ++y)
    for (int x = 0; x < depth_mm.width; ++x) {
      const float z = depth_mm.at(x, y);
      float w = 0.0f;
      double cx = 0, cy = 0;
      Chroma s;
      if (z > 0 &&
          registration.depth_to_color(x, y, static_cast<std::uint16_t>(std::lround(z)), cx, cy) &&
          sample(color, static_cast<int>(cx), static_cast<int>(cy), s))
        w = features.contains(cx, cy) ? 1.0f : static_cast<float>(skin_weight(s, model, options));
      map.at(x, y) = w;
    }
  median_filter(depth_mm, options.median_radius_px, map);
  hair_margin(depth_mm, options.hair_margin_px, map);
  for (int y = 0; y < depth_mm.height; ++y)
    for (int x = 0; x < depth_mm.width; ++x)
      if (depth_mm.at(x, y) > 0) {
        ++with_depth;
        skin += map.at(x, y) >= 0.5f;
      }
  if (stats) {
    stats->samples = model.samples;
    stats->skin_fraction = with_depth ? static_cast<double>(skin) / with_depth : 0.0;
  }
  return map;
}

}  // namespace fb
