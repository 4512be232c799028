#include "algo/wrinkles/detail_blend.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace fb {

namespace {

bool same_size(DetailLayerView a, int w, int h) {
  return a.displacement_mm != nullptr && a.normal_map != nullptr && a.displacement_mm->width == w &&
         a.displacement_mm->height == h && a.normal_map->width == w && a.normal_map->height == h;
}

bool has_detail(DetailLayerView a, std::size_t i) {
  const Rgb8 n = a.normal_map->pixels[i];
  return a.displacement_mm->pixels[i] != 0.0f || n.r != 128 || n.g != 128 || n.b != 255;
}

// dst += w * src: the blend's inner loop. On x86-64 also built for AVX2 and picked at run time
// (8 lanes instead of SSE2's 4; the build targets plain x86-64).
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
[[gnu::target_clones("avx2", "default")]]
#endif
void accumulate(float* dst, const std::int8_t* src, float w, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) dst[i] += w * static_cast<float>(src[i]);
}

// normal_byte() over planes (x, y, z bytes one plane each), in straight loops the compiler
// vectorises: per texel a square root and three conversions, the blend's other cost.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
[[gnu::target_clones("avx2", "default")]]
#endif
void encode_normals(const float* sx, const float* sy, std::uint8_t* out, std::size_t n) {
  std::uint8_t *bx = out, *by = out + n, *bz = out + 2 * n;
  for (std::size_t i = 0; i < n; ++i) {
    const float inv = 1.0f / std::sqrt(sx[i] * sx[i] + sy[i] * sy[i] + 1.0f);
    bx[i] = static_cast<std::uint8_t>(
        static_cast<int>(std::min(255.0f, 127.5f * (sx[i] * inv + 1.0f) + 0.5f)));
    by[i] = static_cast<std::uint8_t>(
        static_cast<int>(std::min(255.0f, 127.5f * (sy[i] * inv + 1.0f) + 0.5f)));
    bz[i] =
        static_cast<std::uint8_t>(static_cast<int>(std::min(255.0f, 127.5f * (inv + 1.0f) + 0.5f)));
  }
}

}  // namespace

void DetailBlend::channels_of(DetailLayerView layer, std::size_t texel, float* out) {
  const Rgb8 n = layer.normal_map->pixels[texel];
  const float x = n.r / 127.5f - 1.0f, y = n.g / 127.5f - 1.0f;
  const float z = std::max(0.2f, n.b / 127.5f - 1.0f);  // a steep texel keeps a finite slope
  out[0] = layer.displacement_mm->pixels[texel];
  out[1] = x / z;
  out[2] = y / z;
}

Rgb8 DetailBlend::normal_byte(float sx, float sy) {
  const float inv = 1.0f / std::sqrt(sx * sx + sy * sy + 1.0f);
  // Rounded by truncating v + 0.5 (v >= 0.5 here): std::lround is a library call, and this
  // runs once per support texel per frame.
  auto byte = [](float v) {
    return static_cast<std::uint8_t>(std::min(255.0f, 127.5f * (v + 1.0f) + 0.5f));
  };
  return {byte(sx * inv), byte(sy * inv), byte(inv)};
}

Result<DetailBlend> DetailBlend::build(DetailLayerView neutral,
                                       std::span<const DetailLayerView> expressions,
                                       std::span<const std::vector<float>> expression_weights,
                                       int shape_count) {
  if (neutral.displacement_mm == nullptr || neutral.normal_map == nullptr)
    return fail("the detail blend needs the neutral's maps");
  if (expressions.size() != expression_weights.size())
    return fail("the detail blend needs one weight recipe per expression");
  if (shape_count <= 0) return fail("the detail blend needs the rig's shapes");
  DetailBlend b;
  b.width_ = neutral.displacement_mm->width;
  b.height_ = neutral.displacement_mm->height;
  for (const auto& e : expressions)
    if (!same_size(e, b.width_, b.height_) || !same_size(neutral, b.width_, b.height_))
      return fail("every detail map of a rig must have the same size");
  for (const auto& w : expression_weights)
    if (w.size() != static_cast<std::size_t>(shape_count))
      return fail("a weight recipe does not have one weight per shape");
  const std::size_t texels = neutral.displacement_mm->pixels.size();
  for (std::size_t i = 0; i < texels; ++i) {
    bool any = has_detail(neutral, i);
    for (const auto& e : expressions) any = any || has_detail(e, i);
    if (any) b.support_.push_back(static_cast<std::uint32_t>(i));
  }
  const std::size_t ns = b.support_.size(), n = ns * kChannels;
  b.neutral_.resize(n);
  float c[kChannels];
  for (std::size_t t = 0; t < ns; ++t) {
    channels_of(neutral, b.support_[t], c);
    for (int k = 0; k < kChannels; ++k) b.neutral_[k * ns + t] = c[k];
  }
  b.shape_count_ = shape_count;
  std::vector<float> delta(n);
  for (const auto& e : expressions) {
    for (std::size_t t = 0; t < ns; ++t) {
      channels_of(e, b.support_[t], c);
      for (int k = 0; k < kChannels; ++k) delta[k * ns + t] = c[k] - b.neutral_[k * ns + t];
    }
    std::vector<std::int8_t> q(n);
    for (int k = 0; k < kChannels; ++k) {
      float peak = 0.0f;
      for (std::size_t t = 0; t < ns; ++t) peak = std::max(peak, std::abs(delta[k * ns + t]));
      const float step = peak > 0.0f ? peak / 127.0f : 1.0f;
      for (std::size_t t = 0; t < ns; ++t)
        q[k * ns + t] = static_cast<std::int8_t>(std::lround(delta[k * ns + t] / step));
      b.scales_.push_back(step);
    }
    b.deltas_.push_back(std::move(q));
  }
  auto weights = MapWeights::build(expression_weights, shape_count);
  if (!weights) return weights.failure();
  b.weights_ = std::move(*weights);
  return b;
}

int DetailBlend::detailed_shapes() const {
  int out = 0;
  for (int s = 0; s < shape_count_; ++s) {
    bool any = false;
    for (int e = 0; e < capture_count(); ++e) any = any || coefficient(s, e) != 0.0f;
    out += any;
  }
  return out;
}

void DetailBlend::prepare(BlendedDetail& out) const {
  out.displacement_mm.resize(width_, height_);
  std::fill(out.displacement_mm.pixels.begin(), out.displacement_mm.pixels.end(), 0.0f);
  out.normal_map.resize(width_, height_);
  std::fill(out.normal_map.pixels.begin(), out.normal_map.pixels.end(), Rgb8{128, 128, 255});
  out.channels.resize(neutral_.size());
  out.capture_weights.resize(deltas_.size());
  out.bytes.resize(neutral_.size());
}

void DetailBlend::apply(std::span<const float> weights, BlendedDetail& out) const {
  // c = P^T a: each capture's share of the frame.
  const std::size_t ne = deltas_.size();
  map_weights(weights, out.capture_weights);
  std::copy(neutral_.begin(), neutral_.end(), out.channels.begin());
  float* acc = out.channels.data();
  const std::size_t ns = support_.size();
  for (std::size_t e = 0; e < ne; ++e) {
    const float c = out.capture_weights[e];
    if (c == 0.0f) continue;
    for (int k = 0; k < kChannels; ++k) {
      const float w = c * scales_[e * kChannels + static_cast<std::size_t>(k)];
      accumulate(acc + k * ns, deltas_[e].data() + k * ns, w, ns);
    }
  }
  encode_normals(acc + ns, acc + 2 * ns, out.bytes.data(), ns);
  const float* d = acc;
  const std::uint8_t *bx = out.bytes.data(), *by = bx + ns, *bz = by + ns;
  for (std::size_t t = 0; t < ns; ++t) {
    out.displacement_mm.pixels[support_[t]] = d[t];
    out.normal_map.pixels[support_[t]] = {bx[t], by[t], bz[t]};
  }
}

}  // namespace fb
