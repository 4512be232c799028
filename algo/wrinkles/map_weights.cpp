#include "algo/wrinkles/map_weights.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>

namespace fb {

Result<MapWeights> MapWeights::build(std::span<const std::vector<float>> recipes, int shape_count) {
  if (shape_count <= 0) return fail("the map weights need the rig's shapes");
  for (const auto& w : recipes) {
    if (w.size() != static_cast<std::size_t>(shape_count))
      return fail("a weight recipe does not have one weight per shape");
    if (!std::all_of(w.begin(), w.end(), [](float v) { return std::isfinite(v); }))
      return fail("a weight recipe has a non-finite weight");
  }
  MapWeights m;
  m.shape_count_ = shape_count;
  m.capture_count_ = static_cast<int>(recipes.size());
  m.coeff_.assign(static_cast<std::size_t>(shape_count) * recipes.size(), 0.0f);
  if (recipes.empty()) return m;
  // P = pinv(W), shapes x captures: the minimum-norm least-squares inverse, so dependent
  // recipes still give finite weights.
  const auto ne = static_cast<Eigen::Index>(recipes.size());
  Eigen::MatrixXd w(ne, shape_count);
  for (Eigen::Index e = 0; e < ne; ++e)
    for (int s = 0; s < shape_count; ++s)
      w(e, s) = recipes[static_cast<std::size_t>(e)][static_cast<std::size_t>(s)];
  const Eigen::MatrixXd pinv = w.completeOrthogonalDecomposition().pseudoInverse();
  for (int s = 0; s < shape_count; ++s)
    for (Eigen::Index e = 0; e < ne; ++e) {
      const double p = std::abs(pinv(s, e)) < 1e-9 ? 0.0 : pinv(s, e);
      m.coeff_[static_cast<std::size_t>(s) * recipes.size() + static_cast<std::size_t>(e)] =
          static_cast<float>(p);
    }
  return m;
}

void MapWeights::apply(std::span<const float> weights, std::span<float> out) const {
  const auto ne = static_cast<std::size_t>(capture_count_);
  const std::size_t n = std::min(ne, out.size());
  std::fill(out.begin(), out.end(), 0.0f);
  const std::size_t ns = std::min(weights.size(), static_cast<std::size_t>(shape_count_));
  for (std::size_t s = 0; s < ns; ++s) {
    const float a = weights[s];
    if (a == 0.0f) continue;
    const float* row = coeff_.data() + s * ne;
    for (std::size_t e = 0; e < n; ++e) out[e] += a * row[e];
  }
}

}  // namespace fb
