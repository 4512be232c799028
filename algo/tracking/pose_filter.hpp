// Filtered head pose: double exponential smoothing (Holt's level + trend) of the translation
// and, through the rotation's log map, of the quaternion. Noise is averaged while a constant
// angular/linear velocity passes through without lag (a plain low-pass, e.g. One Euro, lags a
// turning head by about v / (2 pi fc), i.e. a degree at 30 deg/s and 5 Hz). The level gain
// drops when the innovation is small compared with `noise_*` (jitter at rest is smoothed more).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "algo/core/camera_model.hpp"

namespace fb {

struct PoseFilterOptions {
  double level_gain = 0.6;             // alpha: weight of the new measurement in the level
  double trend_gain = 0.3;             // beta: weight of the new level step in the trend
  double rest_level_gain = 0.25;       // alpha when the innovation is below the noise
  double noise_rotation_rad = 0.0015;  // ~0.1 deg
  double noise_translation_mm = 0.3;
};

class PoseFilter {
 public:
  explicit PoseFilter(const PoseFilterOptions& options = {}) : options_(options) {}
  void reset() { initialised_ = false; }
  // Feeds one raw pose taken `dt_s` after the previous one; returns the filtered pose.
  RigidPose update(const RigidPose& raw, double dt_s);

 private:
  PoseFilterOptions options_;
  bool initialised_ = false;
  Eigen::Quaterniond rotation_ = Eigen::Quaterniond::Identity();
  Eigen::Vector3d translation_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d angular_trend_ = Eigen::Vector3d::Zero();  // rad per second (camera frame)
  Eigen::Vector3d linear_trend_ = Eigen::Vector3d::Zero();   // mm per second
};

}  // namespace fb
