#include "algo/tracking/depth_filter.hpp"

#include <cassert>
#include <cstring>

namespace fb {
namespace {

// 4-lane floats (GCC vector extensions; SSE on x86, NEON on ARM).
using V4f = float __attribute__((vector_size(16)));

inline V4f load4(const float* p) {
  V4f v;
  std::memcpy(&v, p, sizeof v);
  return v;
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

}  // namespace fb
