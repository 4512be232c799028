// The quality check a capture's fit passes before it is stored as done: the device's QA
// (firmware/daemon) and the host's evaluation apply the same rule with the same defaults.
#pragma once

#include "algo/fitting/face_fit.hpp"

namespace fb {

struct FitQaLimits {
  double max_fit_rms_mm = 1.5;         // RMS distance of the fitted mesh to the fused depth
  double max_landmark_error_mm = 6.0;  // mean landmark residual of the fit
};

// Mean residual of the target's valid landmarks on the fit (3D for interior points, ray
// distance for contour points), mm; 0 when none is valid.
double mean_landmark_residual_mm(const FitResult& fit, const FitTarget& target);

// Whether the fit passes both limits (a NaN figure fails).
bool fit_passes_qa(const FitResult& fit, const FitTarget& target, const FitQaLimits& limits = {});

}  // namespace fb
