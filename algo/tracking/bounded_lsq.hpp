// Box-constrained convex quadratic: min 1/2 w^T H w - g^T w subject to lo <= w <= hi, by
// projected Gauss-Seidel (coordinate descent with clamping). H symmetric positive definite
// (the Tikhonov/temporal terms guarantee it), so each coordinate step is an exact minimisation
// and the sweep converges to the unique box-constrained minimum (it is NNLS with an upper
// bound when H = A^T A, g = A^T b). Fixed maximum size: no allocation.
#pragma once

#include <algorithm>

#include <Eigen/Core>

namespace fb {

inline constexpr int kMaxTrackedShapes = 64;

using ShapeMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::ColMajor,
                                  kMaxTrackedShapes, kMaxTrackedShapes>;
using ShapeVector = Eigen::Matrix<float, Eigen::Dynamic, 1, Eigen::ColMajor, kMaxTrackedShapes, 1>;

struct BoundedLsqResult {
  int sweeps = 0;
  float max_step = 0.0f;  // largest coordinate change of the last sweep
};

// Solves in place, warm-started from `w` (clamped first). Stops when a sweep changes no
// coordinate by more than `tolerance` or after `max_sweeps`.
inline BoundedLsqResult solve_bounded_lsq(const ShapeMatrix& h, const ShapeVector& g, float lo,
                                          float hi, ShapeVector& w, int max_sweeps = 50,
                                          float tolerance = 1e-4f) {
  const int n = static_cast<int>(g.size());
  for (int j = 0; j < n; ++j) w[j] = std::clamp(w[j], lo, hi);
  BoundedLsqResult result;
  for (int sweep = 0; sweep < max_sweeps; ++sweep) {
    float max_step = 0.0f;
    for (int j = 0; j < n; ++j) {
      const float hjj = h(j, j);
      if (!(hjj > 0.0f)) continue;
      // d/dw_j: (H w)_j - g_j = 0  ->  w_j = w_j - ((H w)_j - g_j) / H_jj, then clamp.
      const float gradient = h.col(j).dot(w) - g[j];
      const float updated = std::clamp(w[j] - gradient / hjj, lo, hi);
      max_step = std::max(max_step, std::abs(updated - w[j]));
      w[j] = updated;
    }
    result.sweeps = sweep + 1;
    result.max_step = max_step;
    if (max_step <= tolerance) break;
  }
  return result;
}

}  // namespace fb
