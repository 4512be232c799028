// Wrinkled blendshapes and tracking (seed 004, section 4; issue 40 item 5): every personal
// blendshape carries a detail map, and a tracked frame's detail is the weight-blended detail,
// E = N + sum_i a_i B_i, on the maps instead of the meshes.
//
// The expressions captured are not the blendshapes: capture e is the neutral plus its guide
// recipe's weights w_e over the shapes. The shapes' detail deltas B are the least-squares
// (minimum-norm) solution of W B = D - N over the captures with detail (W: captures x shapes,
// D - N: each capture's detail minus the neutral's), so that blending at a capture's own weights
// gives back that capture's maps when the recipes are independent (the guide's are).
//
// Maps blend as three channels per texel: the displacement (mm) and the tangent-space normal's
// slopes (x / z, y / z), which are linear in the height for small slopes; the blended normal is
// (sx, sy, 1) normalised. Only texels where some map has detail (the support, a few percent of
// the layout) are stored and blended; the rest of the output stays flat. Since B = P (D - N)
// with P = pinv(W), a frame blends in capture space: c = P^T a (shapes x captures
// multiply-adds), then E = N + sum_e c_e (D_e - N): as many map layers as captures with detail
// (19 at most with the guide) instead of one per blendshape (53). The layers D_e - N are kept
// as 8-bit steps of 1/127 of each channel's largest |delta| (a quarter of the floats' memory
// traffic, which is what a frame's blend costs; the error, <= half a step per capture, is far
// under the synthesis's).
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "algo/core/image.hpp"
#include "algo/core/result.hpp"
#include "algo/wrinkles/exemplar.hpp"
#include "algo/wrinkles/map_weights.hpp"

namespace fb {

// One capture's maps (the UV layout's size; DetailMaps or the store's).
struct DetailLayerView {
  const FloatImage* displacement_mm = nullptr;
  const ColorImage* normal_map = nullptr;
};

// A frame's blended detail: full-size maps (flat outside the support) and the blend's scratch.
struct BlendedDetail {
  FloatImage displacement_mm;
  ColorImage normal_map;
  std::vector<float> channels;         // 3 planes of support texels: displacement, sx, sy
  std::vector<float> capture_weights;  // c = P^T a
  std::vector<std::uint8_t> bytes;     // 3 planes of support texels: the normal map's bytes
};

class DetailBlend {
 public:
  static constexpr int kChannels = 3;  // displacement, slope x, slope y

  // `expression_weights[e]`: capture e's known weights over `shape_count` shapes.
  static Result<DetailBlend> build(DetailLayerView neutral,
                                   std::span<const DetailLayerView> expressions,
                                   std::span<const std::vector<float>> expression_weights,
                                   int shape_count);

  // Sizes `out` (allocates once) and fills it with flat maps.
  void prepare(BlendedDetail& out) const;
  // E = N + sum a_i B_i on the support texels of `out` (prepared); no allocation. Weights
  // beyond shape_count() are ignored, missing ones are 0.
  void apply(std::span<const float> weights, BlendedDetail& out) const;
  // Only the frame's map weights c = P^T a (`out`: capture_count() floats): what a renderer
  // that holds the captures' maps needs per frame to blend them itself (MapWeights::apply).
  void map_weights(std::span<const float> weights, std::span<float> out) const {
    weights_.apply(weights, out);
  }

  int width() const { return width_; }
  int height() const { return height_; }
  int shape_count() const { return shape_count_; }
  int capture_count() const { return static_cast<int>(deltas_.size()); }
  // Shapes that carry detail (a non-zero delta).
  int detailed_shapes() const;
  const std::vector<std::uint32_t>& support() const { return support_; }
  // P (shape s, capture e).
  float coefficient(int s, int e) const { return weights_.coefficient(s, e); }

  // One texel's three channels from a layer's maps, and back to a normal map's bytes.
  static void channels_of(DetailLayerView layer, std::size_t texel, float* out);
  static Rgb8 normal_byte(float slope_x, float slope_y);

 private:
  int width_ = 0, height_ = 0, shape_count_ = 0;
  std::vector<std::uint32_t> support_;
  std::vector<float> neutral_;                    // 3 planes of support texels
  std::vector<std::vector<std::int8_t>> deltas_;  // per capture, 3 planes, quantised
  std::vector<float> scales_;                     // per capture and plane: mm or slope a step
  MapWeights weights_;                            // c = P^T a
};

}  // namespace fb
