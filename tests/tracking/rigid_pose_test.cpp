// RigidPoseF, the float pose fusion's ICP and the tracker's rooms share (algo/core).
#include "algo/core/rigid_pose.hpp"

#include <gtest/gtest.h>

namespace fb {
namespace {

RigidPose example_pose() {
  RigidPose p;
  p.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, 3).normalized()));
  p.translation = {12.0, -40.0, 700.0};
  return p;
}

TEST(RigidPoseF, FollowsRigidPoseAndBack) {
  const RigidPose p = example_pose();
  const RigidPoseF f = RigidPoseF::from(p);
  const Eigen::Vector3d x(30.0, -20.0, 15.0);
  EXPECT_LT((f.apply(x.cast<float>()).cast<double>() - p.apply(x)).norm(), 1e-3);  // mm
  const RigidPose back = f.to_rigid();
  EXPECT_LT(back.rotation.angularDistance(p.rotation), 1e-6);
  EXPECT_LT((back.translation - p.translation).norm(), 1e-4);
  const RigidPoseF identity = f.inverse() * f;
  EXPECT_LT((identity.r - Eigen::Matrix3f::Identity()).norm(), 1e-6f);
  EXPECT_LT(identity.t.norm(), 1e-3f);
}

TEST(RigidPoseF, TwistTurnsAboutItsPivotAndMoves) {
  RigidPoseF f = RigidPoseF::from(example_pose());
  const Eigen::Vector3f model_point(5.0f, 8.0f, -3.0f);
  const Eigen::Vector3f pivot = f.apply(model_point);  // turn about where this point is
  const Eigen::Vector3f elsewhere(-40.0f, 10.0f, 20.0f);
  const Eigen::Vector3f before = f.apply(elsewhere);
  const Eigen::Vector3f omega(0.0f, 0.1f, 0.0f), dt(1.0f, 2.0f, 3.0f);
  f.apply_twist(omega, dt, pivot);
  // The pivot's point only moves by dt; any other point turns about the pivot by |omega|.
  EXPECT_LT((f.apply(model_point) - (pivot + dt)).norm(), 1e-3f);
  const Eigen::Vector3f turned =
      Eigen::AngleAxisf(0.1f, Eigen::Vector3f::UnitY()) * (before - pivot) + pivot + dt;
  EXPECT_LT((f.apply(elsewhere) - turned).norm(), 1e-3f);
}

}  // namespace
}  // namespace fb
