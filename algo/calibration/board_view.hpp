// One frame's observations of the checkerboard plate for the calibration: the colour corners,
// depth samples on the plate and samples of the plate's outline in the depth image.
//
// Depth is in "table" millimetres: the raw disparity through the device's (or the default)
// disparity law without any correction, which the calibration then corrects.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "algo/calibration/board.hpp"
#include "algo/calibration/registration_model.hpp"
#include "algo/core/image.hpp"
#include "algo/core/result.hpp"

namespace fb {

// An outermost plate pixel along a row (axis 0) or column (axis 1) scan; `outward` is +1 when
// the plate's edge lies at larger x (axis 0) or y (axis 1), else -1.
struct EdgeSample {
  float u = 0.0f, v = 0.0f;
  std::int8_t axis = 0;
  std::int8_t outward = 1;
};

struct BoardView {
  std::vector<Eigen::Vector2d> corners_color;  // BoardSpec::corner() order
  std::vector<Eigen::Vector3f> depth;          // (u, v, table mm) inside the plate
  std::vector<EdgeSample> edges;
  // 1 / z_table = a u + b v + c over the plate (a plane under any affine-in-disparity law).
  Eigen::Vector3d inverse_depth_plane = Eigen::Vector3d::Zero();
  double median_depth_mm = 0.0;  // table mm
  int plate_pixels = 0;
};

// Table depth (mm, 0 = none) of a raw disparity image under `tables` (its correction ignored).
Image<float> table_depth(const DisparityImage& raw, const KinectCalibration& tables);

// Finds the plate in the depth image next to the colour corners (the registration may be off
// by tens of pixels: it looks where `model`'s tables put the board, and takes the connected
// planar region there), and collects its depth and outline samples. Fails, saying why, when
// the plate is not seen in depth well enough to use.
Result<BoardView> extract_board_view(const BoardSpec& board, const RegistrationModel& model,
                                     const Image<float>& depth_table_mm,
                                     std::vector<Eigen::Vector2d> corners_color);

}  // namespace fb
