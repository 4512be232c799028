#include "algo/fitting/fit_qa.hpp"

#include <cmath>

namespace fb {

double mean_landmark_residual_mm(const FitResult& fit, const FitTarget& target) {
  double sum = 0;
  int n = 0;
  for (int i = 0; i < kFitLandmarkCount; ++i) {
    const double r = fit.landmark_residual_mm[static_cast<std::size_t>(i)];
    if (target.landmarks[static_cast<std::size_t>(i)].valid && std::isfinite(r)) {
      sum += r;
      ++n;
    }
  }
  return n > 0 ? sum / n : 0.0;
}

bool fit_passes_qa(const FitResult& fit, const FitTarget& target, const FitQaLimits& limits) {
  return fit.rms_to_depth_mm <= limits.max_fit_rms_mm &&
         mean_landmark_residual_mm(fit, target) <= limits.max_landmark_error_mm;
}

}  // namespace fb
