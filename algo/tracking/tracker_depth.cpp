// FaceTracker stage: the depth it fits to. A ring of the last k frames, their temporal mean in
// the predicted face box, then the edge-preserving spatial pass. (The fits read it through
// depth_at(), inline in face_tracker_state.hpp.)
#include <algorithm>
#include <cmath>
#include <cstring>

#include "algo/tracking/depth_filter.hpp"
#include "algo/tracking/face_tracker_state.hpp"

namespace fb {

using namespace tracker_detail;

Box FaceTracker::State::predicted_box(const Pose& p) const {
  float u0 = 1e9f, v0 = 1e9f, u1 = -1e9f, v1 = -1e9f;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3f x = p.r * sample(i) + p.t;
    if (x.z() <= 1.0f) continue;
    const Eigen::Vector2f px = pixel_of(x);
    const float u = px.x(), v = px.y();
    u0 = std::min(u0, u), u1 = std::max(u1, u), v0 = std::min(v0, v), v1 = std::max(v1, v);
  }
  constexpr int kMargin = 16;  // px: a frame's motion plus the bilinear footprint
  Box b;
  b.x0 = std::clamp(static_cast<int>(u0) - kMargin, 0, width);
  b.y0 = std::clamp(static_cast<int>(v0) - kMargin, 0, height);
  b.x1 = std::clamp(static_cast<int>(u1) + kMargin, 0, width);
  b.y1 = std::clamp(static_cast<int>(v1) + kMargin, 0, height);
  return b;
}

int FaceTracker::State::smooth(const DepthImage& depth, const Box& b) {
  // Weighted temporal mean: w_a = decay^a * (1 - (d_a - d_0)^2 / range^2)^2 for frames that
  // agree with the newest within `range`; the newest frame defines validity.
  // Branch-free, 4 pixels at a time (GCC vector extensions: SSE on the host, NEON on the
  // device), the row's remainder one at a time; the arithmetic and its order per pixel are
  // the same in both, so the result does not depend on the grouping.
  const int count = std::min(ring_count, 16);
  const float range = options.temporal_range_mm, inv_range2 = 1.0f / (range * range);
  const float lo = options.min_depth_mm, hi = options.max_depth_mm;
  std::array<const std::uint16_t*, 16> frames{};
  std::array<float, 16> decay{};
  for (int a = 0; a < count; ++a) {
    const int slot =
        (ring_head - a + static_cast<int>(ring.size())) % static_cast<int>(ring.size());
    frames[a] = a == 0 ? depth.pixels.data() : ring[static_cast<std::size_t>(slot)].pixels.data();
    decay[a] = std::pow(options.temporal_decay, static_cast<float>(a));
  }
  const V4f zero4 = {0.0f, 0.0f, 0.0f, 0.0f}, one4 = {1.0f, 1.0f, 1.0f, 1.0f};
  V4i valid4 = {0, 0, 0, 0};  // -1 per valid pixel
  int valid = 0;
  for (int y = b.y0; y < b.y1; ++y) {
    const std::size_t row = static_cast<std::size_t>(y) * width;
    float* out = smoothed.pixels.data() + row;
    int x = b.x0;
    for (; x + 4 <= b.x1; x += 4) {
      const V4f d0 = load4(frames[0] + row + x);
      V4f sum = d0, wsum = one4;
      for (int a = 1; a < count; ++a) {
        const V4f d = load4(frames[a] + row + x);
        const V4f diff = d - d0;
        const V4f q = diff * diff * inv_range2;
        const V4f t = decay[a] * (1.0f - q) * (1.0f - q);
        const V4f w = (d > 0.0f) & (q < 1.0f) ? t : zero4;
        sum += w * d;
        wsum += w;
      }
      const V4i ok = (d0 >= lo) & (d0 <= hi);
      const V4f mean = sum / wsum;  // wsum >= 1
      const V4f result = ok ? mean : zero4;
      std::memcpy(out + x, &result, sizeof result);
      valid4 += ok;
    }
    for (; x < b.x1; ++x) {
      const std::size_t i = row + static_cast<std::size_t>(x);
      const float d0 = frames[0][i];
      if (!(d0 >= lo && d0 <= hi)) {
        out[x] = 0.0f;
        continue;
      }
      float sum = d0, wsum = 1.0f;
      for (int a = 1; a < count; ++a) {
        const float d = frames[a][i];
        const float diff = d - d0;
        const float q = diff * diff * inv_range2;
        if (d <= 0.0f || q >= 1.0f) continue;
        const float w = decay[a] * (1.0f - q) * (1.0f - q);
        sum += w * d;
        wsum += w;
      }
      out[x] = sum / wsum;
      ++valid;
    }
  }
  return valid - (valid4[0] + valid4[1] + valid4[2] + valid4[3]);
}

void FaceTracker::State::smooth_spatially(const Box& b) {
  const int r = options.spatial_radius_px;
  // A box too small for the window has no interior (edge_aware_mean writes nothing either).
  if (r <= 0 || b.x1 - b.x0 <= 2 * r || b.y1 - b.y0 <= 2 * r) return;
  edge_aware_mean(smoothed, b, {.radius_px = r, .range_mm = options.spatial_range_mm},
                  spatial_scratch);
  for (int y = b.y0 + r; y < b.y1 - r; ++y) {
    const auto first = static_cast<std::ptrdiff_t>(y) * width + b.x0 + r;
    std::copy(spatial_scratch.pixels.begin() + first,
              spatial_scratch.pixels.begin() + first + (b.x1 - b.x0 - 2 * r),
              smoothed.pixels.begin() + first);
  }
}

}  // namespace fb
