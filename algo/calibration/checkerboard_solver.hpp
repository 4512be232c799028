// Joint checkerboard calibration of a Kinect v1 unit (after Herrera et al. 2012): from views of
// a printed checkerboard plate, the unit's full RegistrationCorrection relative to its tables
// (colour shift and rotation, depth-law scale and inverse-depth offset).
//
// Unknowns: every view's board pose in the depth camera frame, the correction, and the mean
// distance (px) from the outermost plate pixel to the plate's true edge (the depth image's
// erosion or bleeding at the outline). Residuals, minimised with Levenberg-Marquardt (Huber):
//  (a) colour corners vs the board corners projected into the depth image (depth intrinsics)
//      and mapped to colour by the continuous registration with the correction;
//  (b) table depth on the plate, through the corrected depth law, vs the board's plane;
//  (c) the plate's outline samples vs its projected outline. Without (c) the colour shift
//      trades against the board's in-plane position and is not observable.
// The square size and the depth intrinsics fix the metric scale that the depth law is held to.
#pragma once

#include <span>
#include <string>
#include <vector>

#include "algo/calibration/board.hpp"
#include "algo/calibration/board_view.hpp"
#include "algo/calibration/registration_model.hpp"
#include "algo/core/camera_model.hpp"
#include "algo/core/result.hpp"

namespace fb {

struct CheckerboardOptions {
  int max_iterations = 40;
  int min_views = 4;
  double corner_sigma_px = 0.1;       // colour corner accuracy
  double edge_sigma_px = 0.5;         // outline sample (whole-pixel outline, dropouts)
  double depth_sigma_at_1m_mm = 3.5;  // disparity noise in mm at 1 m (grows as z^2)
};

struct CheckerboardViewResidual {
  RigidPose camera_from_board;
  double color_px_rms = 0.0;
  double depth_mm_rms = 0.0;  // corrected depth vs the board's plane
  double edge_px_rms = 0.0;
};

struct CheckerboardResult {
  RegistrationCorrection correction;
  std::vector<CheckerboardViewResidual> views;
  double color_px_rms = 0.0;
  double depth_mm_rms = 0.0;
  double edge_px_rms = 0.0;
  double edge_offset_px = 0.0;
  int iterations = 0;
};

// `model` must be built from the unit's tables without a correction (the reported calibration
// with its correction cleared). Fails, saying why, with fewer than min_views views or when the
// solve does not converge.
Result<CheckerboardResult> solve_checkerboard(const BoardSpec& board,
                                              const RegistrationModel& model,
                                              const PinholeIntrinsics& depth_intrinsics,
                                              std::span<const BoardView> views,
                                              const CheckerboardOptions& options = {});

// Largest distance between where two registration corrections put the colour image's centre
// and corners (colour px): a registration difference in one number.
double registration_difference_px(const RegistrationCorrection& a, const RegistrationCorrection& b);

// The depth a unit with correction `estimate` reports for a point that a unit with correction
// `truth` measures at `true_mm` (same tables): how far the estimated depth law is off there.
double depth_law_ratio(const RegistrationCorrection& estimate, const RegistrationCorrection& truth,
                       double true_mm);

}  // namespace fb
