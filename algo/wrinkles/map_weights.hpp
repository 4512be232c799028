// A tracked frame's wrinkle map weights (seed 004 section 4, issue 40 item 5): one weight per
// captured expression with detail maps, c = P^T a, P = pinv(W), W the captures' guide recipes
// over the face model's shapes (captures x shapes), a the frame's shape weights. The frame's
// detail is then E = N + sum_e c_e (D_e - N) (detail_blend.hpp). The one implementation of the
// coefficients: the host's DetailBlend (which also blends the maps) and the booth's tracking
// mode (which streams only c) both use it.
#pragma once

#include <span>
#include <vector>

#include "algo/core/result.hpp"

namespace fb {

class MapWeights {
 public:
  // `recipes[e]`: capture e's known weights over `shape_count` shapes. No recipe is allowed
  // (capture_count() 0: every frame's weights are empty).
  static Result<MapWeights> build(std::span<const std::vector<float>> recipes, int shape_count);

  // c = P^T a into `out` (capture_count() floats; a shorter `out` gets the first ones). Weights
  // beyond shape_count() are ignored, missing ones are 0. No allocation.
  void apply(std::span<const float> weights, std::span<float> out) const;

  int shape_count() const { return shape_count_; }
  int capture_count() const { return capture_count_; }
  // P (shape s, capture e); entries under 1e-9 are exactly 0.
  float coefficient(int s, int e) const {
    return coeff_[static_cast<std::size_t>(s) * static_cast<std::size_t>(capture_count_) +
                  static_cast<std::size_t>(e)];
  }

 private:
  int shape_count_ = 0, capture_count_ = 0;
  std::vector<float> coeff_;  // P, shapes x captures, row-major
};

}  // namespace fb
