#include "algo/tracking/depth_smoother.hpp"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <cstring>

namespace fb {
namespace {

// 4-lane float / int vectors (GCC vector extensions; SSE on x86, NEON on ARM).
using V4f = float __attribute__((vector_size(16)));
using V4i = int __attribute__((vector_size(16)));
using V4u16 = std::uint16_t __attribute__((vector_size(8)));

inline V4f load4(const float* p) {
  V4f v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

// 4 consecutive depth pixels (mm) as floats.
inline V4f load4(const std::uint16_t* p) {
  V4u16 packed;
  std::memcpy(&packed, p, sizeof packed);
  return __builtin_convertvector(packed, V4f);
}

}  // namespace

void edge_aware_mean(const Image<float>& in, const PixelRect& rect,
                     const EdgeAwareMeanOptions& options, Image<float>& out) {
  assert(in.width == out.width && in.height == out.height && &in != &out);
  const int r = options.radius_px;
  const PixelRect inner{rect.x0 + r, rect.y0 + r, rect.x1 - r, rect.y1 - r};
  if (r <= 0 || inner.empty()) return;
  const float range = options.range_mm;
  const std::ptrdiff_t stride = in.width;
  const V4f zero4 = {0.0f, 0.0f, 0.0f, 0.0f}, one4 = {1.0f, 1.0f, 1.0f, 1.0f};
  for (int y = inner.y0; y < inner.y1; ++y) {
    const float* src = in.pixels.data() + y * stride;
    float* dst = out.pixels.data() + y * stride;
    int x = inner.x0;
    // 4 pixels at a time, then the row's remainder with the same arithmetic.
    for (; x + 4 <= inner.x1; x += 4) {
      const V4f d0 = load4(src + x);
      V4f sum = zero4, count = zero4;
      for (int dy = -r; dy <= r; ++dy) {
        for (int dx = -r; dx <= r; ++dx) {
          const V4f d = load4(src + dy * stride + x + dx);
          const V4f diff = d - d0;
          const auto near = (d > 0.0f) & (diff < range) & (diff > -range);
          sum += near ? d : zero4;
          count += near ? one4 : zero4;
        }
      }
      const V4f result = d0 > 0.0f ? sum / count : zero4;  // count >= 1: the centre
      std::memcpy(dst + x, &result, sizeof result);
    }
    for (; x < inner.x1; ++x) {
      const float d0 = src[x];
      float sum = 0.0f, count = 0.0f;
      for (int dy = -r; dy <= r; ++dy) {
        for (int dx = -r; dx <= r; ++dx) {
          const float d = src[dy * stride + x + dx];
          const float diff = d - d0;
          const bool near = d > 0.0f && diff < range && diff > -range;
          sum += near ? d : 0.0f;
          count += near ? 1.0f : 0.0f;
        }
      }
      dst[x] = d0 > 0.0f ? sum / count : 0.0f;
    }
  }
}

void DepthSmoother::allocate(const DepthSmootherOptions& options, int width, int height) {
  options_ = options;
  width_ = width;
  ring_.resize(static_cast<std::size_t>(options.temporal_frames));
  for (auto& f : ring_) f.resize(width, height);
  smoothed_.resize(width, height);
  spatial_scratch_.resize(width, height);
}

void DepthSmoother::push(const DepthImage& depth) {
  ring_head_ = (ring_head_ + 1) % static_cast<int>(ring_.size());
  std::copy(depth.pixels.begin(), depth.pixels.end(),
            ring_[static_cast<std::size_t>(ring_head_)].pixels.begin());
  ring_count_ = std::min(ring_count_ + 1, static_cast<int>(ring_.size()));
}

int DepthSmoother::smooth(const DepthImage& depth, const PixelRect& rect) {
  const int valid = smooth_temporally(depth, rect);
  smooth_spatially(rect);
  return valid;
}

int DepthSmoother::smooth_temporally(const DepthImage& depth, const PixelRect& b) {
  // Weighted temporal mean: w_a = decay^a * (1 - (d_a - d_0)^2 / range^2)^2 for frames that
  // agree with the newest within `range`; the newest frame defines validity.
  // Branch-free, 4 pixels at a time (GCC vector extensions: SSE on the host, NEON on the
  // device), the row's remainder one at a time; the arithmetic and its order per pixel are
  // the same in both, so the result does not depend on the grouping.
  const int count = std::min(ring_count_, 16);
  const float range = options_.temporal_range_mm, inv_range2 = 1.0f / (range * range);
  const float lo = options_.min_depth_mm, hi = options_.max_depth_mm;
  const int width = width_;
  std::array<const std::uint16_t*, 16> frames{};
  std::array<float, 16> decay{};
  for (int a = 0; a < count; ++a) {
    const int slot =
        (ring_head_ - a + static_cast<int>(ring_.size())) % static_cast<int>(ring_.size());
    frames[a] = a == 0 ? depth.pixels.data() : ring_[static_cast<std::size_t>(slot)].pixels.data();
    decay[a] = std::pow(options_.temporal_decay, static_cast<float>(a));
  }
  const V4f zero4 = {0.0f, 0.0f, 0.0f, 0.0f}, one4 = {1.0f, 1.0f, 1.0f, 1.0f};
  V4i valid4 = {0, 0, 0, 0};  // -1 per valid pixel
  int valid = 0;
  for (int y = b.y0; y < b.y1; ++y) {
    const std::size_t row = static_cast<std::size_t>(y) * width;
    float* out = smoothed_.pixels.data() + row;
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

void DepthSmoother::smooth_spatially(const PixelRect& b) {
  const int r = options_.spatial_radius_px;
  // A box too small for the window has no interior (edge_aware_mean writes nothing either).
  if (r <= 0 || b.x1 - b.x0 <= 2 * r || b.y1 - b.y0 <= 2 * r) return;
  edge_aware_mean(smoothed_, b, {.radius_px = r, .range_mm = options_.spatial_range_mm},
                  spatial_scratch_);
  for (int y = b.y0 + r; y < b.y1 - r; ++y) {
    const auto first = static_cast<std::ptrdiff_t>(y) * width_ + b.x0 + r;
    std::copy(spatial_scratch_.pixels.begin() + first,
              spatial_scratch_.pixels.begin() + first + (b.x1 - b.x0 - 2 * r),
              smoothed_.pixels.begin() + first);
  }
}

}  // namespace fb
