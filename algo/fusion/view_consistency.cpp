#include "algo/fusion/view_consistency.hpp"

#include <algorithm>
#include <cmath>

namespace fb {

Result<void> ViewConsistency::reset(const PinholeIntrinsics& intrinsics,
                                    const ViewConsistencyOptions& options) {
  if (intrinsics.width <= 0 || intrinsics.height <= 0 || !(intrinsics.fx > 0) ||
      !(intrinsics.fy > 0))
    return fail("view consistency: the reference camera has no valid intrinsics");
  if (!(options.gate_mm > 0) || !(options.full_seen_fraction > 0) ||
      !(options.half_confidence_scatter_mm > 0))
    return fail("view consistency: gate, seen fraction and scatter must be > 0");
  k_ = intrinsics;
  options_ = options;
  cells_.assign(static_cast<std::size_t>(intrinsics.width) * intrinsics.height, Cell{});
  scratch_.clear();
  scratch_.reserve(cells_.size());
  frames_ = 0;
  return success();
}

namespace {

// Bilinear depth of `m` at full-resolution pixel (x, y) when `m` is `scale` times coarser;
// 0 unless all four samples have depth within 20 mm of each other (no silhouette blend).
float sample_model(const Image<float>& m, int scale, int x, int y) {
  const float u = (static_cast<float>(x) + 0.5f) / static_cast<float>(scale) - 0.5f;
  const float v = (static_cast<float>(y) + 0.5f) / static_cast<float>(scale) - 0.5f;
  const int u0 = static_cast<int>(std::floor(u)), v0 = static_cast<int>(std::floor(v));
  if (u0 < 0 || v0 < 0 || u0 + 1 >= m.width || v0 + 1 >= m.height) return 0.0f;
  const float a = m.at(u0, v0), b = m.at(u0 + 1, v0), c = m.at(u0, v0 + 1),
              d = m.at(u0 + 1, v0 + 1);
  if (a <= 0.0f || b <= 0.0f || c <= 0.0f || d <= 0.0f) return 0.0f;
  if (std::max({a, b, c, d}) - std::min({a, b, c, d}) > 20.0f) return 0.0f;
  const float fu = u - static_cast<float>(u0), fv = v - static_cast<float>(v0);
  return (a * (1 - fu) + b * fu) * (1 - fv) + (c * (1 - fu) + d * fu) * fv;
}

}  // namespace

void ViewConsistency::add(const DepthImage& depth_mm, const Image<float>& model_depth,
                          const RigidPose& reference_from_camera, const PixelRect& box) {
  if (cells_.empty() || depth_mm.width <= 0 || depth_mm.height <= 0 || model_depth.width <= 0)
    return;
  const int scale = std::max(1, depth_mm.width / model_depth.width);
  ++frames_;
  const Eigen::Matrix3f r = reference_from_camera.rotation.toRotationMatrix().cast<float>();
  const Eigen::Vector3f t = reference_from_camera.translation.cast<float>();
  const PixelRect frame_rect{0, 0, depth_mm.width, depth_mm.height};
  const PixelRect area = box.empty() ? frame_rect : box.clipped(depth_mm.width, depth_mm.height);
  // The frame's own camera is the reference's (one sensor).
  const float fx = static_cast<float>(k_.fx), fy = static_cast<float>(k_.fy);
  const float cx = static_cast<float>(k_.cx), cy = static_cast<float>(k_.cy);
  for (int y = area.y0; y < area.y1; ++y)
    for (int x = area.x0; x < area.x1; ++x) {
      const float z = depth_mm.at(x, y);
      if (z <= 0.0f) continue;
      const float zm = sample_model(model_depth, scale, x, y);
      if (zm <= 0.0f) continue;
      const float d = std::clamp(z - zm, -options_.gate_mm, options_.gate_mm);
      const Eigen::Vector3f p((static_cast<float>(x) - cx) * zm / fx,
                              (static_cast<float>(y) - cy) * zm / fy, zm);
      const Eigen::Vector3f q = r * p + t;
      if (q.z() <= 1.0f) continue;
      const int u = static_cast<int>(std::lround(fx * q.x() / q.z() + cx));
      const int v = static_cast<int>(std::lround(fy * q.y() / q.z() + cy));
      if (u < 0 || v < 0 || u >= k_.width || v >= k_.height) continue;
      Cell& c = cells_[static_cast<std::size_t>(v) * k_.width + u];
      c.sum += d;
      c.sum2 += d * d;
      ++c.count;
    }
}

void ViewConsistency::confidence(Image<float>& out) {
  out.resize(k_.width, k_.height);
  const float full = std::max(1.0f, options_.full_seen_fraction * static_cast<float>(frames_));
  const float s2 = options_.half_confidence_scatter_mm * options_.half_confidence_scatter_mm;
  auto variance = [](const Cell& c) {
    const float n = static_cast<float>(c.count);
    const float mean = c.sum / n;
    return std::max(0.0f, c.sum2 / n - mean * mean);
  };
  scratch_.clear();
  for (const Cell& c : cells_)
    if (static_cast<float>(c.count) >= full) scratch_.push_back(variance(c));
  float typical = 0.0f;
  if (!scratch_.empty()) {
    auto mid = scratch_.begin() + static_cast<std::ptrdiff_t>(scratch_.size() / 2);
    std::nth_element(scratch_.begin(), mid, scratch_.end());
    typical = *mid;
  }
  for (int y = 0; y < k_.height; ++y)
    for (int x = 0; x < k_.width; ++x) {
      const Cell& c = cells_[static_cast<std::size_t>(y) * k_.width + x];
      if (c.count == 0) {
        out.at(x, y) = 0.0f;
        continue;
      }
      const float seen = std::min(1.0f, static_cast<float>(c.count) / full);
      out.at(x, y) = seen * std::min(1.0f, (s2 + typical) / (s2 + variance(c)));
    }
}

}  // namespace fb
