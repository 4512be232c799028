// Pinhole intrinsics and rigid poses. Camera coordinates follow OpenCV:
// x right, y down, z forward, millimetres.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace fb {

struct PinholeIntrinsics {
  int width = 640;
  int height = 480;
  double fx = 0.0;
  double fy = 0.0;
  double cx = 0.0;
  double cy = 0.0;

  Eigen::Vector2d project(const Eigen::Vector3d& p) const {
    return {fx * p.x() / p.z() + cx, fy * p.y() / p.z() + cy};
  }
  Eigen::Vector3d unproject(double u, double v, double depth) const {
    return {(u - cx) * depth / fx, (v - cy) * depth / fy, depth};
  }
};

// Maps points from a source frame into a target frame: p_target = rotation * p_source +
// translation.
struct RigidPose {
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();  // millimetres

  Eigen::Vector3d apply(const Eigen::Vector3d& p) const { return rotation * p + translation; }
  Eigen::Isometry3d isometry() const {
    Eigen::Isometry3d m = Eigen::Isometry3d::Identity();
    m.linear() = rotation.toRotationMatrix();
    m.translation() = translation;
    return m;
  }
  RigidPose inverse() const {
    RigidPose inv;
    inv.rotation = rotation.conjugate();
    inv.translation = -(inv.rotation * translation);
    return inv;
  }
};

// The pose of frame b in frame a, from both in a common world: a_from_b = w_from_a^-1 w_from_b.
inline RigidPose relative_pose(const RigidPose& world_from_a, const RigidPose& world_from_b) {
  const RigidPose a_from_world = world_from_a.inverse();
  RigidPose p;
  p.rotation = a_from_world.rotation * world_from_b.rotation;
  p.translation = a_from_world.apply(world_from_b.translation);
  return p;
}

}  // namespace fb
