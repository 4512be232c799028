// The Kinect v1 depth-to-colour registration as a continuous function, for sub-pixel work
// (checkerboard corners, the synthetic board's analytic colour render). libfreenect's tables are
// defined at whole depth pixels; between them the rectified position is interpolated bilinearly
// and the depth parallax linearly between whole millimetres, so the model agrees with
// KinectRegistration::depth_to_color() at every depth pixel and whole millimetre.
//
// colour(u, v, z) = R(theta) (rect(u, v) - centre) + centre + (dx, dy) + (parallax(z), 0)
// where rect is the table of the registration the model was built from and the correction
// (theta, dx, dy) is applied on top (identity = the tables as they are).
#pragma once

#include <cmath>
#include <vector>

#include <Eigen/Core>

#include "algo/sensor/kinect_calibration.hpp"

namespace fb {

class RegistrationModel {
 public:
  // Tables of `registration` as they are (including any correction they were built with).
  explicit RegistrationModel(const KinectRegistration& registration);

  // Bilinear rectified colour position at depth pixel (u, v) and optionally its Jacobian
  // d rect / d(u, v). False outside the table.
  bool rectified(double u, double v, Eigen::Vector2d& position,
                 Eigen::Matrix2d* jacobian = nullptr) const;
  // Parallax along colour x at depth z (mm), and optionally d parallax / dz (px per mm).
  double parallax(double z_mm, double* derivative = nullptr) const;

  // The correction's transform of a rectified position (rotation about the colour image centre,
  // then the shift).
  static Eigen::Vector2d apply(const RegistrationCorrection& correction, const Eigen::Vector2d& q);
  static Eigen::Vector2d centre() { return {(640 - 1) / 2.0, (480 - 1) / 2.0}; }

  // Full colour position of depth pixel (u, v) at depth z under `correction`.
  bool color_position(const RegistrationCorrection& correction, double u, double v, double z_mm,
                      Eigen::Vector2d& color) const;

  // The depth pixel whose colour position is `color` on a surface given by z(u, v) (e.g. a
  // plane), starting from `uv`. Returns false when it does not converge or leaves the table.
  template <class DepthOf>
  bool depth_pixel_of(const RegistrationCorrection& correction, const Eigen::Vector2d& color,
                      DepthOf&& depth_of, Eigen::Vector2d& uv) const;

  // Mean affine map rect(u, v) ~ A (u, v) + b over the table, used to start and safeguard the
  // inversion.
  const Eigen::Matrix2d& mean_jacobian() const { return mean_jacobian_; }

 private:
  std::vector<double> rect_x_, rect_y_;  // 640 x 480, NaN where the table has no entry
  std::vector<double> parallax_;         // per whole mm
  Eigen::Matrix2d mean_jacobian_ = Eigen::Matrix2d::Identity();
};

template <class DepthOf>
bool RegistrationModel::depth_pixel_of(const RegistrationCorrection& correction,
                                       const Eigen::Vector2d& color, DepthOf&& depth_of,
                                       Eigen::Vector2d& uv) const {
  const double angle = correction.rotation_deg * 3.14159265358979323846 / 180.0;
  Eigen::Matrix2d rotation;
  rotation << std::cos(angle), -std::sin(angle), std::sin(angle), std::cos(angle);
  const Eigen::Matrix2d mean_inverse = (rotation * mean_jacobian_).inverse();
  // The error at a depth pixel and the local (piecewise bilinear) Jacobian there.
  auto evaluate = [&](const Eigen::Vector2d& at, Eigen::Vector2d& error, Eigen::Matrix2d& local) {
    const double z = depth_of(at.x(), at.y());
    Eigen::Vector2d q;
    Eigen::Matrix2d j;
    if (!(z > 0.0) || !rectified(at.x(), at.y(), q, &j)) return false;
    error = color - (apply(correction, q) + Eigen::Vector2d(parallax(z), 0.0));
    local = rotation * j;
    return true;
  };
  Eigen::Vector2d error;
  Eigen::Matrix2d local;
  if (!evaluate(uv, error, local)) return false;
  // Newton with backtracking; far away, or where the table repeats a row (a cell whose local
  // slope is near 0), the mean slope is the better step.
  for (int iteration = 0; iteration < 40; ++iteration) {
    if (error.squaredNorm() < 1e-10) return true;
    const bool newton =
        error.squaredNorm() < 4.0 &&
        std::abs(local.determinant()) > 0.05 * std::abs(mean_jacobian_.determinant());
    const Eigen::Vector2d step =
        newton ? Eigen::Vector2d(local.inverse() * error) : Eigen::Vector2d(mean_inverse * error);
    bool moved = false;
    for (double scale = 1.0; scale > 0.01 && !moved; scale *= 0.5) {
      Eigen::Vector2d next_error;
      Eigen::Matrix2d next_local;
      const Eigen::Vector2d next = uv + scale * step;
      if (evaluate(next, next_error, next_local) && next_error.norm() < error.norm()) {
        uv = next, error = next_error, local = next_local;
        moved = true;
      }
    }
    if (moved) continue;
    // Stuck in a cell that repeats a row: leave it along the mean step.
    const Eigen::Vector2d mean_step = mean_inverse * error;
    double exit = 200.0;
    for (int axis = 0; axis < 2; ++axis) {
      if (std::abs(mean_step[axis]) < 1e-12) continue;
      const double boundary =
          mean_step[axis] > 0 ? std::floor(uv[axis]) + 1.0 : std::floor(uv[axis]);
      exit = std::min(exit, (boundary - uv[axis]) / mean_step[axis] + 1e-4);
    }
    uv += std::max(exit, 1.0) * mean_step;
    if (!evaluate(uv, error, local)) return false;
  }
  return error.squaredNorm() < 1e-6;
}

}  // namespace fb
