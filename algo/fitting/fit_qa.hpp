// The quality check a capture's fit passes before it is stored as done: the device's QA
// (firmware/daemon) and the host's evaluation apply the same rule with the same defaults.
#pragma once

#include "algo/fitting/face_fit.hpp"

namespace fb {

struct FitQaLimits {
  double max_fit_rms_mm = 1.5;         // RMS distance of the fitted mesh to the fused depth
  double max_landmark_error_mm = 6.0;  // landmark_disagreement_mm() of the fit
};

// How far the fit and the target's landmarks disagree, mm: the median 3D residual of the valid
// interior points (17-67); 0 when none is valid. Not the contour: its points slide along the
// fitted region's outline, whose distance to a detector's jaw line is the region's shape more
// than the fit (dlib: 6-9 mm on good fits). The median, because a detector misplaces a few
// points of an open mouth by a centimetre while the fit is right; a face fitted in the wrong
// place moves them all.
double landmark_disagreement_mm(const FitResult& fit, const FitTarget& target);

// Whether the fit passes both limits (a NaN figure fails).
bool fit_passes_qa(const FitResult& fit, const FitTarget& target, const FitQaLimits& limits = {});

}  // namespace fb
