#include "algo/calibration/board_detection.hpp"

#include <algorithm>
#include <cmath>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

namespace fb {

Result<std::vector<Eigen::Vector2d>> detect_board_corners(const ColorImage& color,
                                                          const BoardSpec& board) {
  if (color.empty()) return fail("no colour image in this frame");
  cv::Mat grey(color.height, color.width, CV_8UC1);
  for (int y = 0; y < color.height; ++y) {
    for (int x = 0; x < color.width; ++x) {
      const Rgb8 p = color.at(x, y);
      grey.at<std::uint8_t>(y, x) =
          static_cast<std::uint8_t>((77 * p.r + 150 * p.g + 29 * p.b) >> 8);
    }
  }
  const cv::Size pattern(board.cols, board.rows);
  std::vector<cv::Point2f> found;
  const int flags =
      cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE | cv::CALIB_CB_FAST_CHECK;
  // Small boards (squares under ~12 px, boards beyond ~1.2 m) are found more reliably in an
  // upscaled image; the corners are refined in the original either way.
  bool ok = cv::findChessboardCorners(grey, pattern, found, flags);
  if (!ok) {
    cv::Mat larger;
    cv::resize(grey, larger, cv::Size(), 2.0, 2.0, cv::INTER_LINEAR);
    ok = cv::findChessboardCorners(larger, pattern, found, flags);
    for (auto& p : found) p = cv::Point2f((p.x - 0.5f) / 2.0f, (p.y - 0.5f) / 2.0f);
  }
  if (!ok || static_cast<int>(found.size()) != board.corner_count()) {
    return fail("no " + std::to_string(board.cols) + "x" + std::to_string(board.rows) +
                " checkerboard found in the colour image");
  }
  // Refinement window: under half the corner spacing, so it sees one corner only.
  double spacing = 1e9;
  for (int j = 0; j + 1 < board.corner_count(); ++j) {
    if ((j + 1) % board.cols != 0) {
      spacing = std::min(spacing, static_cast<double>(cv::norm(found[j + 1] - found[j])));
    }
  }
  const int half = std::clamp(static_cast<int>(spacing * 0.4), 2, 8);
  cv::cornerSubPix(grey, found, cv::Size(half, half), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::EPS | cv::TermCriteria::COUNT, 50, 1e-4));
  std::vector<Eigen::Vector2d> corners;
  for (const auto& p : found) corners.emplace_back(p.x, p.y);
  // Order: the outer square diagonally beyond corner 0 must be the black one; else reverse.
  const Eigen::Vector2d step_x = corners[1] - corners[0];
  const Eigen::Vector2d step_y = corners[static_cast<std::size_t>(board.cols)] - corners[0];
  auto grey_at = [&](const Eigen::Vector2d& p) {
    const int x = std::clamp(static_cast<int>(std::lround(p.x())), 0, color.width - 1);
    const int y = std::clamp(static_cast<int>(std::lround(p.y())), 0, color.height - 1);
    return static_cast<int>(grey.at<std::uint8_t>(y, x));
  };
  const Eigen::Vector2d first = corners.front() - 0.5 * (step_x + step_y);
  const Eigen::Vector2d last_step_x = corners[corners.size() - 1] - corners[corners.size() - 2];
  const Eigen::Vector2d last_step_y =
      corners.back() - corners[corners.size() - 1 - static_cast<std::size_t>(board.cols)];
  const Eigen::Vector2d last = corners.back() + 0.5 * (last_step_x + last_step_y);
  if (grey_at(first) > grey_at(last)) std::reverse(corners.begin(), corners.end());
  return corners;
}

}  // namespace fb
