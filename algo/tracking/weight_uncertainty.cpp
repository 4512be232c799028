#include "algo/tracking/weight_uncertainty.hpp"

#include <array>
#include <cmath>
#include <limits>

#include <Eigen/Cholesky>

namespace fb {

void weight_standard_errors(const ShapeMatrix& information, float min_information,
                            ShapeVector& sigma) {
  const auto k = static_cast<int>(information.rows());
  sigma.setConstant(k, std::numeric_limits<float>::infinity());
  std::array<int, kMaxTrackedShapes> seen{};
  int m = 0;
  for (int j = 0; j < k; ++j)
    if (information(j, j) > min_information) seen[static_cast<std::size_t>(m++)] = j;
  if (m == 0) return;
  ShapeMatrix sub(m, m);
  for (int a = 0; a < m; ++a)
    for (int b = 0; b < m; ++b)
      sub(a, b) = information(seen[static_cast<std::size_t>(a)], seen[static_cast<std::size_t>(b)]);
  const Eigen::LDLT<ShapeMatrix> ldlt(sub);
  ShapeVector unit = ShapeVector::Zero(m), column(m);
  for (int a = 0; a < m; ++a) {
    // (I^-1)_aa = e_a^T I^-1 e_a: one solve per shape, m^3 in all (53 shapes: ~0.1 ms).
    unit[a] = 1.0f;
    column = ldlt.solve(unit);
    unit[a] = 0.0f;
    const float variance = column[a];
    if (variance > 0.0f) sigma[seen[static_cast<std::size_t>(a)]] = std::sqrt(variance);
  }
}

}  // namespace fb
