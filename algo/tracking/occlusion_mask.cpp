#include "algo/tracking/occlusion_mask.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace fb {

void OcclusionMask::mark(const OcclusionMaskOptions& options, const SubjectRig& rig,
                         const TrackerCamera& camera, const Image<float>& image, const PixelRect& b,
                         const RigidPoseF& p, const TrackLandmarks* detected_points) {
  // A sample is hidden when the depth at its pixel, or at one of 8 pixels occluder_radius_px
  // away, is nearer than the model point by more than occluder_margin_mm. The margin is above
  // the face's own relief (the nose stands ~30 mm off the cheeks).
  const float margin = options.occluder_margin_mm;
  on = margin > 0.0f;
  if (!on) return;
  const int width = camera.width;
  // Pass 1, the sample's own pixel; pass 2 (only when pass 1 found an occluder: the common
  // unoccluded frame pays one read a sample) the 8 pixels around it.
  const int r = std::max(0, options.occluder_radius_px);
  const std::array<std::array<int, 2>, 8> offsets = {
      {{-r, 0}, {r, 0}, {0, -r}, {0, r}, {-r, -r}, {r, -r}, {-r, r}, {r, r}}};
  auto nearer_at = [&](int px, int py, float nearer) {
    if (px < b.x0 || py < b.y0 || px >= b.x1 || py >= b.y1) return false;
    const float d = image.pixels[static_cast<std::size_t>(py) * width + px];
    return d > 0.0f && d < nearer;
  };
  auto pixel = [&](int i, int& u, int& v, float& nearer) {
    const Eigen::Vector3f x = p.r * rig.sample(i) + p.t;
    if (x.z() <= 1.0f) return false;
    const Eigen::Vector2f px = camera.pixel_of(x);
    u = static_cast<int>(std::lround(px.x()));
    v = static_cast<int>(std::lround(px.y()));
    nearer = x.z() - margin;
    return true;
  };
  bool any = false;
  for (int i = 0; i < rig.n; ++i) {
    int u = 0, v = 0;
    float nearer = 0.0f;
    const bool hidden = pixel(i, u, v, nearer) && nearer_at(u, v, nearer);
    samples[static_cast<std::size_t>(i)] = hidden ? 1 : 0;
    any = any || hidden;
  }
  landmarks.fill(0);
  if (!any) return;
  // A landmark is hidden by the same test at its model point or at the detected point (a
  // detector's point on the hand has the hand's depth): own pixel and the 8 around it.
  const bool detected = detected_points != nullptr && detected_points->points.size() >= 68;
  auto hidden_around = [&](int u, int v, float nearer) {
    if (nearer_at(u, v, nearer)) return true;
    for (std::size_t o = 0; o < offsets.size() && r > 0; ++o)
      if (nearer_at(u + offsets[o][0], v + offsets[o][1], nearer)) return true;
    return false;
  };
  for (int l = 0; l < 68; ++l) {
    const Eigen::Vector3f x = rig.landmark_in_camera(p, l);
    if (x.z() <= 1.0f) continue;
    const float nearer = x.z() - margin;
    const Eigen::Vector2f px = camera.pixel_of(x);
    bool hidden = hidden_around(static_cast<int>(std::lround(px.x())),
                                static_cast<int>(std::lround(px.y())), nearer);
    if (!hidden && detected) {
      const Eigen::Vector2f& q = detected_points->points[static_cast<std::size_t>(l)];
      hidden = hidden_around(static_cast<int>(std::lround(q.x())),
                             static_cast<int>(std::lround(q.y())), nearer);
    }
    landmarks[static_cast<std::size_t>(l)] = hidden ? 1 : 0;
  }
  // A shape predictor places its points jointly: with most of the inner face covered, the
  // points that look free are placed by the covered ones too, so none is used.
  const int hidden_inner = std::accumulate(landmarks.begin() + 17, landmarks.end(), 0);
  if (hidden_inner > options.max_hidden_landmark_fraction * 51.0f) landmarks.fill(1);
  if (r == 0) return;
  for (int i = 0; i < rig.n; ++i) {
    auto& hidden = samples[static_cast<std::size_t>(i)];
    int u = 0, v = 0;
    float nearer = 0.0f;
    if (hidden || !pixel(i, u, v, nearer)) continue;
    for (const auto& [dx, dy] : offsets) {
      if (nearer_at(u + dx, v + dy, nearer)) {
        hidden = 1;
        break;
      }
    }
  }
}

}  // namespace fb
