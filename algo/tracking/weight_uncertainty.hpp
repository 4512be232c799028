// How well one frame's data pins each blendshape weight down: the standard error of the
// linearised least-squares weight solve without its priors (the Cramer-Rao bound given the
// pose). The tracker reports it on request (TrackerOptions::report_weight_sigma) so that an
// error can be told apart from what the frame's data allows: a brow seen by depth alone has a
// standard error of ~0.1, a jaw of ~0.01.
#pragma once

#include "algo/tracking/bounded_lsq.hpp"

namespace fb {

// sigma_j = sqrt((I^-1)_jj), with I the Fisher information of the weights (sum over the
// frame's rows of J^T J / sigma_row^2), inverted over the shapes the data sees at all
// (I_jj > min_information); the others get +inf. Fixed maximum size: no allocation.
void weight_standard_errors(const ShapeMatrix& information, float min_information,
                            ShapeVector& sigma);

}  // namespace fb
