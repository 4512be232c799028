#include "algo/calibration/checkerboard_calibrator.hpp"

#include <algorithm>

#include "algo/calibration/board_detection.hpp"

namespace fb {
namespace {

KinectCalibration without_correction(KinectCalibration c) {
  c.correction = RegistrationCorrection{};
  return c;
}

}  // namespace

CheckerboardCalibrator::CheckerboardCalibrator(const BoardSpec& board,
                                               const KinectCalibration& calibration)
    : board_(board),
      tables_(without_correction(calibration)),
      model_(KinectRegistration(tables_)) {}

Result<void> CheckerboardCalibrator::add_frame(const ColorImage& color, const DisparityImage& raw,
                                               const DepthImage& depth_mm) {
  auto corners = detect_board_corners(color, board_);
  if (!corners) return corners.failure();
  Image<float> depth;
  if (!raw.empty()) {
    depth = table_depth(raw, tables_);
  } else {
    depth.resize(depth_mm.width, depth_mm.height);
    for (std::size_t i = 0; i < depth.pixels.size(); ++i) depth.pixels[i] = depth_mm.pixels[i];
  }
  auto view = extract_board_view(board_, model_, depth, std::move(*corners));
  if (!view) return fail("board found in colour, but " + view.error().message);
  views_.push_back(std::move(*view));
  return success();
}

std::array<int, CheckerboardCalibrator::kGridCols * CheckerboardCalibrator::kGridRows>
CheckerboardCalibrator::coverage() const {
  std::array<int, kGridCols * kGridRows> cells{};
  for (const auto& view : views_) {
    // Every cell a corner of this view falls in counts once.
    std::array<bool, kGridCols * kGridRows> seen{};
    for (const auto& c : view.corners_color) {
      const int col = std::clamp(static_cast<int>(c.x() / (640.0 / kGridCols)), 0, kGridCols - 1);
      const int row = std::clamp(static_cast<int>(c.y() / (480.0 / kGridRows)), 0, kGridRows - 1);
      seen[static_cast<std::size_t>(row * kGridCols + col)] = true;
    }
    for (std::size_t i = 0; i < cells.size(); ++i) cells[i] += seen[i] ? 1 : 0;
  }
  return cells;
}

double CheckerboardCalibrator::min_depth_mm() const {
  double d = 0.0;
  for (const auto& v : views_) d = d == 0.0 ? v.median_depth_mm : std::min(d, v.median_depth_mm);
  return d;
}

double CheckerboardCalibrator::max_depth_mm() const {
  double d = 0.0;
  for (const auto& v : views_) d = std::max(d, v.median_depth_mm);
  return d;
}

std::string CheckerboardCalibrator::hint() const {
  const auto cells = coverage();
  const auto emptiest = std::min_element(cells.begin(), cells.end()) - cells.begin();
  static const char* kRows[] = {"top", "middle", "bottom"};
  static const char* kCols[] = {"far left", "left", "right", "far right"};
  std::string hint;
  if (cells[static_cast<std::size_t>(emptiest)] < 2) {
    hint = std::string("hold the board in the ") + kRows[emptiest / kGridCols] + " " +
           kCols[emptiest % kGridCols] + " of the image";
  }
  if (views_.empty() || min_depth_mm() > 800.0) {
    hint += std::string(hint.empty() ? "" : "; ") + "bring the board nearer (0.6-0.8 m)";
  } else if (max_depth_mm() < 1200.0) {
    hint += std::string(hint.empty() ? "" : "; ") + "move the board farther away (1.2-1.5 m)";
  }
  return hint;
}

Result<CheckerboardResult> CheckerboardCalibrator::solve(const CheckerboardOptions& options) const {
  return solve_checkerboard(board_, model_, tables_.depth_intrinsics(), views_, options);
}

KinectCalibration CheckerboardCalibrator::calibrated(
    const RegistrationCorrection& correction) const {
  KinectCalibration c = tables_;
  c.correction = correction;
  return c;
}

}  // namespace fb
