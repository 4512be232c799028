#include "algo/tracking/pose_filter.hpp"

#include <algorithm>
#include <cmath>

namespace fb {
namespace {

Eigen::Vector3d log_map(const Eigen::Quaterniond& q) {
  Eigen::Quaterniond s = q.normalized();
  if (s.w() < 0.0) s.coeffs() = -s.coeffs();  // shortest way round
  const Eigen::AngleAxisd aa(s);
  return aa.angle() * aa.axis();
}

Eigen::Quaterniond exp_map(const Eigen::Vector3d& v) {
  const double angle = v.norm();
  if (angle < 1e-12) return Eigen::Quaterniond::Identity();
  return Eigen::Quaterniond(Eigen::AngleAxisd(angle, v / angle));
}

// Level gain between rest_gain (innovation within the noise) and gain (beyond 3x the noise).
double adaptive_gain(double innovation, double noise, double rest_gain, double gain) {
  const double s = std::clamp((innovation / noise - 1.0) / 2.0, 0.0, 1.0);
  return rest_gain + s * (gain - rest_gain);
}

}  // namespace

RigidPose PoseFilter::update(const RigidPose& raw, double dt_s) {
  const Eigen::Quaterniond q = raw.rotation.normalized();
  if (!initialised_ || !(dt_s > 0.0) || dt_s > 0.5) {
    // Start, or a gap (loss): no trend to extrapolate.
    initialised_ = true;
    rotation_ = q;
    translation_ = raw.translation;
    angular_trend_.setZero();
    linear_trend_.setZero();
    return raw;
  }
  // Rotation (camera frame, left-multiplied): predict with the trend, correct by the
  // innovation, and update the trend from the level step.
  const Eigen::Quaterniond predicted = (exp_map(angular_trend_ * dt_s) * rotation_).normalized();
  const Eigen::Vector3d innovation = log_map(q * predicted.conjugate());
  const double ar = adaptive_gain(innovation.norm(), options_.noise_rotation_rad,
                                  options_.rest_level_gain, options_.level_gain);
  const Eigen::Quaterniond level = (exp_map(ar * innovation) * predicted).normalized();
  const Eigen::Vector3d step = log_map(level * rotation_.conjugate()) / dt_s;
  angular_trend_ += options_.trend_gain * (step - angular_trend_);
  rotation_ = level;

  const Eigen::Vector3d predicted_t = translation_ + linear_trend_ * dt_s;
  const Eigen::Vector3d innovation_t = raw.translation - predicted_t;
  const double at = adaptive_gain(innovation_t.norm(), options_.noise_translation_mm,
                                  options_.rest_level_gain, options_.level_gain);
  const Eigen::Vector3d level_t = predicted_t + at * innovation_t;
  linear_trend_ += options_.trend_gain * ((level_t - translation_) / dt_s - linear_trend_);
  translation_ = level_t;

  RigidPose out;
  out.rotation = rotation_;
  out.translation = translation_;
  return out;
}

}  // namespace fb
