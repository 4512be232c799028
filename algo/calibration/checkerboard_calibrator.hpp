// The checkerboard calibration as a pipeline over frames: find the board in each colour image,
// collect its depth observations, then solve (checkerboard_solver.hpp). What `camera
// calibrate`, `eval calibration` and the tests run. Keeps per-frame outcomes for the progress
// display (which frames had a board, image coverage, depth range).
#pragma once

#include <array>
#include <string>
#include <vector>

#include "algo/calibration/board.hpp"
#include "algo/calibration/board_view.hpp"
#include "algo/calibration/checkerboard_solver.hpp"
#include "algo/calibration/registration_model.hpp"
#include "algo/core/image.hpp"

namespace fb {

class CheckerboardCalibrator {
 public:
  static constexpr int kGridCols = 4, kGridRows = 3;  // coarse image coverage grid

  // `calibration`: what the camera reports; its tables are used and its correction ignored (the
  // result is a correction relative to the tables).
  CheckerboardCalibrator(const BoardSpec& board, const KinectCalibration& calibration);

  // One frame: colour image and the raw disparity (preferred) or, when the backend has none,
  // depth in mm under the tables' law. A frame without a usable board is reported as a
  // failure saying why; it is not used.
  Result<void> add_frame(const ColorImage& color, const DisparityImage& raw,
                         const DepthImage& depth_mm);

  int views() const { return static_cast<int>(views_.size()); }
  const std::vector<BoardView>& board_views() const { return views_; }
  // Views whose board centre falls in each coverage cell (row-major kGridCols x kGridRows).
  std::array<int, kGridCols * kGridRows> coverage() const;
  double min_depth_mm() const;
  double max_depth_mm() const;
  // A hint for the next board placement: the emptiest image region and depth band, or "".
  std::string hint() const;

  Result<CheckerboardResult> solve(const CheckerboardOptions& options = {}) const;
  // The calibration to store: the tables with the solved correction.
  KinectCalibration calibrated(const RegistrationCorrection& correction) const;

 private:
  BoardSpec board_;
  KinectCalibration tables_;
  RegistrationModel model_;
  std::vector<BoardView> views_;
};

}  // namespace fb
