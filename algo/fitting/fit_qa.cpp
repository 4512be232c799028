#include "algo/fitting/fit_qa.hpp"

#include <algorithm>
#include <array>
#include <cmath>

namespace fb {

double landmark_disagreement_mm(const FitResult& fit, const FitTarget& target) {
  std::array<double, kFitLandmarkCount> r{};
  std::size_t n = 0;
  for (int i = 0; i < kFitLandmarkCount; ++i) {
    const double d = fit.landmark_residual_mm[static_cast<std::size_t>(i)];
    if (!is_contour_landmark(i) && target.landmarks[static_cast<std::size_t>(i)].valid &&
        std::isfinite(d))
      r[n++] = d;
  }
  if (n == 0) return 0.0;
  const auto mid = r.begin() + static_cast<std::ptrdiff_t>(n / 2);
  std::nth_element(r.begin(), mid, r.begin() + static_cast<std::ptrdiff_t>(n));
  if (n % 2 == 1) return *mid;
  return 0.5 * (*mid + *std::max_element(r.begin(), mid));
}

bool fit_passes_qa(const FitResult& fit, const FitTarget& target, const FitQaLimits& limits) {
  return fit.rms_to_depth_mm <= limits.max_fit_rms_mm &&
         landmark_disagreement_mm(fit, target) <= limits.max_landmark_error_mm;
}

}  // namespace fb
