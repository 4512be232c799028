#include "algo/landmarks/face_region_box.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include "algo/landmarks/landmark_lifting.hpp"

namespace fb {

FaceProportions face_proportions(const FaceModel& model) {
  FaceProportions out;
  const int n = std::min(model.face_vertex_count, model.vertex_count);
  if (n <= 0 || model.neutral.size() < static_cast<std::size_t>(3 * model.vertex_count)) return out;
  auto at = [&](std::uint32_t v) {
    return Eigen::Vector3d(model.neutral[3 * v], model.neutral[3 * v + 1],
                           model.neutral[3 * v + 2]);
  };
  Eigen::Vector2d lo(1e9, 1e9), hi(-1e9, -1e9);
  for (std::uint32_t v : model.landmark_vertices) {
    const Eigen::Vector3d p = at(v);
    lo = lo.cwiseMin(p.head<2>());
    hi = hi.cwiseMax(p.head<2>());
  }
  // Which way is up: the brows (17-26) against the chin (8); which way the face looks: the nose
  // tip (30) against the eye corners (36, 45).
  const Eigen::Vector3d chin = at(model.landmark_vertices[8]);
  const double up = at(model.landmark_vertices[19]).y() > chin.y() ? 1.0 : -1.0;
  const double front =
      at(model.landmark_vertices[30]).z() >
              0.5 * (at(model.landmark_vertices[36]).z() + at(model.landmark_vertices[45]).z())
          ? 1.0
          : -1.0;
  const Eigen::Vector2d size = hi - lo;
  if (!(size.x() > 0.0) || !(size.y() > 0.0)) return out;
  const double top_landmark = up > 0 ? hi.y() : lo.y();
  // The forehead: the face region's highest vertices (99th percentile, so a few stray rim
  // vertices do not set it). The chin: only its front (within 15 mm of the chin point's depth
  // and 30 % of the face's width of it), not the underside and neck, which hang over the
  // chest and do not move with the head the way the face does.
  std::vector<double> above, sides;
  double below = 0.0;
  for (int v = 0; v < n; ++v) {
    const Eigen::Vector3d p = at(static_cast<std::uint32_t>(v));
    above.push_back(up * (p.y() - top_landmark));
    const double down = up * (chin.y() - p.y());
    if (down > 0.0 && std::abs(p.x() - chin.x()) < 0.3 * size.x() &&
        front * (p.z() - chin.z()) > -15.0)
      below = std::max(below, down);
    if (up * (p.y() - chin.y()) >= 0.0 && up * (top_landmark - p.y()) >= 0.0 &&
        front * (p.z() - chin.z()) > -15.0)
      sides.push_back(std::max(lo.x() - p.x(), p.x() - hi.x()));
  }
  auto pct = [](std::vector<double>& a, double q) {
    if (a.empty()) return 0.0;
    const std::size_t k = static_cast<std::size_t>(q * static_cast<double>(a.size() - 1));
    std::nth_element(a.begin(), a.begin() + static_cast<std::ptrdiff_t>(k), a.end());
    return a[k];
  };
  out.above = std::max(0.0, pct(above, 0.99) / size.y());
  out.below = std::max(0.0, below / size.y());
  out.sides = std::max(0.0, pct(sides, 0.99) / size.x());
  return out;
}

Result<FaceBox> face_box_from_landmarks(std::span<const FitLandmark> landmarks,
                                        const FaceProportions& proportions, int width, int height,
                                        const FaceRegionOptions& options) {
  Eigen::Vector2d lo(1e9, 1e9), hi(-1e9, -1e9);
  std::vector<double> depths;
  int valid = 0;
  for (const FitLandmark& l : landmarks) {
    if (!l.valid) continue;
    ++valid;
    lo = lo.cwiseMin(l.pixel);
    hi = hi.cwiseMax(l.pixel);
    if (l.point && l.point->z() > 0.0) depths.push_back(l.point->z());
  }
  if (valid < 20)
    return fail("only " + std::to_string(valid) +
                " of the face's landmarks fall in the depth image (20 needed to place the face "
                "box): the face is at the image's edge or the registration is off");
  const Eigen::Vector2d size = hi - lo;
  double x0 = lo.x() - proportions.sides * size.x(), x1 = hi.x() + proportions.sides * size.x();
  double y0 = lo.y() - proportions.above * size.y(), y1 = hi.y() + proportions.below * size.y();
  const double w = x1 - x0, h = y1 - y0;
  x0 -= options.side_margin * w;
  x1 += options.side_margin * w;
  y0 -= options.top_margin * h;
  y1 += options.bottom_margin * h;
  FaceBox box;
  box.rect = {static_cast<int>(std::floor(x0)), static_cast<int>(std::floor(y0)),
              static_cast<int>(std::ceil(x1)) + 1, static_cast<int>(std::ceil(y1)) + 1};
  if (!depths.empty()) {
    const auto mid = depths.begin() + static_cast<std::ptrdiff_t>(depths.size() / 2);
    std::nth_element(depths.begin(), mid, depths.end());
    box.face_depth_mm = static_cast<float>(*mid);
  }
  box = box.clipped(width, height);
  if (box.rect.width() < 16 || box.rect.height() < 16)
    return fail("the detected face covers too little of the depth image to fuse");
  return box;
}

void set_chin_cut(std::span<const FitLandmark> landmarks, const PinholeIntrinsics& k,
                  FaceBox& box) {
  box.chin_mm = box.down = Eigen::Vector3f::Zero();
  if (landmarks.size() != 68 || !(k.fx > 0.0) || !(k.fy > 0.0) || !landmarks[8].valid ||
      !landmarks[27].valid || !(box.face_depth_mm > 0.0f))
    return;
  // The depth of a group of lifted points (strict lifting leaves rims 2D), else the face's.
  auto depth_of = [&](int first, int last) {
    double sum = 0.0;
    int n = 0;
    for (int i = first; i <= last; ++i)
      if (const auto& p = landmarks[static_cast<std::size_t>(i)].point) {
        sum += p->z();
        ++n;
      }
    return n > 0 ? sum / n : static_cast<double>(box.face_depth_mm);
  };
  const Eigen::Vector2d& b = landmarks[27].pixel;
  const Eigen::Vector2d& c = landmarks[8].pixel;
  const Eigen::Vector3d bridge = k.unproject(b.x(), b.y(), depth_of(27, 28));
  const Eigen::Vector3d chin = k.unproject(c.x(), c.y(), depth_of(48, 59));
  const Eigen::Vector3d axis = chin - bridge;
  // Nasion to chin is 100-140 mm on adults; anything far outside is not a face.
  if (!(axis.norm() > 60.0 && axis.norm() < 220.0)) return;
  box.chin_mm = chin.cast<float>();
  box.down = axis.normalized().cast<float>();
}

Result<DetectedFaceRegion> detect_face_region(LandmarkDetector& detector, const ColorImage& color,
                                              const DepthImage& depth,
                                              const KinectRegistration& registration,
                                              const FaceProportions& proportions,
                                              const FaceRegionOptions& options) {
  if (color.empty()) return fail("the frame has no colour image to find the face in");
  detector.reset_tracking();
  auto found = detector.detect(color);
  if (!found) return found.failure();
  const Image<float> depth_mm = depth_to_float(depth);
  auto lifted = lift_landmarks(found->points, depth_mm, registration);
  if (!lifted) return lifted.failure();
  auto box = face_box_from_landmarks(*lifted, proportions, depth.width, depth.height, options);
  if (!box) return box.failure();
  DetectedFaceRegion out;
  out.box = *box;
  set_chin_cut(*lifted, registration.depth_intrinsics(), out.box);
  out.color_points = found->points;
  return out;
}

}  // namespace fb
