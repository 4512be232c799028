// Rigid poses: RigidPose (double, quaternion; defined with the camera model in
// camera_model.hpp, which most of the tree includes) is what modules exchange and filter;
// RigidPoseF (float, matrix) is its working form in the hot loops of tracking and fusion, where
// a 3x3 float product per point is the cost that matters. Both map points from a source frame
// into a target frame: p_target = R p_source + t (mm).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "algo/core/camera_model.hpp"

namespace fb {

struct RigidPoseF {
  Eigen::Matrix3f r = Eigen::Matrix3f::Identity();
  Eigen::Vector3f t = Eigen::Vector3f::Zero();

  Eigen::Vector3f apply(const Eigen::Vector3f& p) const { return r * p + t; }
  RigidPoseF inverse() const { return {r.transpose(), -(r.transpose() * t)}; }
  RigidPoseF operator*(const RigidPoseF& o) const { return {r * o.r, r * o.t + t}; }
  // The small motion (omega, dt) about `pivot` (target frame): x' = Rw (x - pivot) + pivot + dt.
  void apply_twist(const Eigen::Vector3f& omega, const Eigen::Vector3f& dt,
                   const Eigen::Vector3f& pivot) {
    const float angle = omega.norm();
    const Eigen::Matrix3f rw = angle > 1e-9f
                                   ? Eigen::AngleAxisf(angle, omega / angle).toRotationMatrix()
                                   : Eigen::Matrix3f::Identity();
    r = rw * r;
    t = rw * (t - pivot) + pivot + dt;
  }
  static RigidPoseF from(const RigidPose& p) {
    return {p.rotation.toRotationMatrix().cast<float>(), p.translation.cast<float>()};
  }
  RigidPose to_rigid() const {
    RigidPose p;
    p.rotation = Eigen::Quaterniond(r.cast<double>()).normalized();
    p.translation = t.cast<double>();
    return p;
  }
};

}  // namespace fb
