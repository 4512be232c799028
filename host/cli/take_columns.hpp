// A stored take's columns: where each ARKit curve sits (takes name their shapes in ARKit's
// camelCase or in Live Link's capitalised form, algo/tracking/arkit.hpp), and the head pose.
#pragma once

#include <array>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "algo/core/camera_model.hpp"
#include "algo/tracking/arkit.hpp"
#include "storage/session_store.hpp"

namespace fb::cli {

// column[k] = the take column of ARKit curve k, -1 where the take lacks it.
inline std::array<int, kArkitShapeCount> arkit_columns(const std::vector<std::string>& names) {
  std::array<int, kArkitShapeCount> column;
  column.fill(-1);
  for (int k = 0; k < kArkitShapeCount; ++k)
    for (std::size_t i = 0; i < names.size(); ++i)
      if (names[i] == kArkitNames[k] || names[i] == kLiveLinkNames[k]) {
        column[k] = static_cast<int>(i);
        break;
      }
  return column;
}

// Frame f's ARKit curves in Apple's order (0 where the take lacks the curve).
inline std::array<float, kArkitShapeCount> arkit_curves(
    const TakeData& take, const std::array<int, kArkitShapeCount>& column, int f) {
  std::array<float, kArkitShapeCount> out{};
  const auto v = take.frame(f);
  for (int k = 0; k < kArkitShapeCount; ++k)
    out[k] = column[k] >= 0 ? v[kTakePoseValues + column[k]] : 0.0f;
  return out;
}

// Frame f's head pose, camera_from_model (stored tx ty tz in mm, then qx qy qz qw).
inline RigidPose take_pose(const TakeData& take, int f) {
  const auto v = take.frame(f);
  RigidPose pose;
  pose.translation = Eigen::Vector3d(v[0], v[1], v[2]);
  pose.rotation = Eigen::Quaterniond(v[6], v[3], v[4], v[5]).normalized();
  return pose;
}

}  // namespace fb::cli
