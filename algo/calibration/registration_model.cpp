#include "algo/calibration/registration_model.hpp"

#include <cmath>
#include <limits>

namespace fb {
namespace {
constexpr int kWidth = 640, kHeight = 480, kMaxMm = 10000;
}

RegistrationModel::RegistrationModel(const KinectRegistration& registration) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  rect_x_.assign(static_cast<std::size_t>(kWidth) * kHeight, nan);
  rect_y_.assign(rect_x_.size(), nan);
  // Least-squares affine fit of the table (for the mean Jacobian).
  Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
  Eigen::Matrix<double, 3, 2> rhs = Eigen::Matrix<double, 3, 2>::Zero();
  for (int y = 0; y < kHeight; ++y) {
    for (int x = 0; x < kWidth; ++x) {
      double cx = 0.0, cy = 0.0;
      if (!registration.rectified_position(x, y, cx, cy)) continue;
      const std::size_t i = static_cast<std::size_t>(y) * kWidth + x;
      rect_x_[i] = cx;
      rect_y_[i] = cy;
      if (x % 4 == 0 && y % 4 == 0) {
        const Eigen::Vector3d a(x, y, 1.0);
        normal += a * a.transpose();
        rhs += a * Eigen::RowVector2d(cx, cy);
      }
    }
  }
  const Eigen::Matrix<double, 3, 2> affine = normal.ldlt().solve(rhs);
  mean_jacobian_ = affine.topRows<2>().transpose();
  parallax_.assign(kMaxMm, 0.0);
  for (int mm = 1; mm < kMaxMm; ++mm) {
    parallax_[mm] = registration.parallax_px(static_cast<std::uint16_t>(mm));
  }
}

bool RegistrationModel::rectified(double u, double v, Eigen::Vector2d& position,
                                  Eigen::Matrix2d* jacobian) const {
  if (!(u >= 0.0 && v >= 0.0 && u <= kWidth - 1 && v <= kHeight - 1)) return false;
  const int x0 = std::min(static_cast<int>(u), kWidth - 2);
  const int y0 = std::min(static_cast<int>(v), kHeight - 2);
  const double fx = u - x0, fy = v - y0;
  const std::size_t i = static_cast<std::size_t>(y0) * kWidth + x0;
  const std::size_t n[4] = {i, i + 1, i + kWidth, i + kWidth + 1};
  Eigen::Vector2d q[4];
  for (int k = 0; k < 4; ++k) {
    q[k] = {rect_x_[n[k]], rect_y_[n[k]]};
    if (std::isnan(q[k].x())) return false;
  }
  position = (1 - fy) * ((1 - fx) * q[0] + fx * q[1]) + fy * ((1 - fx) * q[2] + fx * q[3]);
  if (jacobian != nullptr) {
    jacobian->col(0) = (1 - fy) * (q[1] - q[0]) + fy * (q[3] - q[2]);
    jacobian->col(1) = (1 - fx) * (q[2] - q[0]) + fx * (q[3] - q[1]);
  }
  return true;
}

double RegistrationModel::parallax(double z_mm, double* derivative) const {
  if (!(z_mm >= 1.0 && z_mm < kMaxMm - 1)) {
    if (derivative != nullptr) *derivative = 0.0;
    return 0.0;
  }
  const auto lo = static_cast<std::size_t>(z_mm);
  const double slope = parallax_[lo + 1] - parallax_[lo];
  if (derivative != nullptr) *derivative = slope;
  return parallax_[lo] + slope * (z_mm - static_cast<double>(lo));
}

Eigen::Vector2d RegistrationModel::apply(const RegistrationCorrection& correction,
                                         const Eigen::Vector2d& q) {
  const double angle = correction.rotation_deg * 3.14159265358979323846 / 180.0;
  const double c = std::cos(angle), s = std::sin(angle);
  const Eigen::Vector2d d = q - centre();
  return centre() + Eigen::Vector2d(c * d.x() - s * d.y() + correction.dx_px,
                                    s * d.x() + c * d.y() + correction.dy_px);
}

bool RegistrationModel::color_position(const RegistrationCorrection& correction, double u, double v,
                                       double z_mm, Eigen::Vector2d& color) const {
  Eigen::Vector2d q;
  if (!(z_mm > 0.0) || !rectified(u, v, q)) return false;
  color = apply(correction, q) + Eigen::Vector2d(parallax(z_mm), 0.0);
  return true;
}

}  // namespace fb
