// Finding the printed checkerboard in a colour image (OpenCV's findChessboardCorners, refined
// with cornerSubPix). The only part of algo/calibration that uses OpenCV.
#pragma once

#include <vector>

#include <Eigen/Core>

#include "algo/calibration/board.hpp"
#include "algo/core/image.hpp"
#include "algo/core/result.hpp"

namespace fb {

// The board's inner corners in colour pixels (pixel centres at integer coordinates), ordered as
// BoardSpec::corner() (the black outer square at the first corner). Fails when the whole
// board is not found, saying so.
Result<std::vector<Eigen::Vector2d>> detect_board_corners(const ColorImage& color,
                                                          const BoardSpec& board);

}  // namespace fb
