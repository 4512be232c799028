// Error figures of eval fit beyond the mean vertex error: the eye and mouth region (where a
// refinement that follows holes and depth jumps shows first) and the capture QA rule.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "algo/core/camera_model.hpp"
#include "algo/facemodel/face_model.hpp"

namespace fb::cli {

// The model's fitting vertices within `radius_mm` of an eye-contour (iBUG 36-47) or mouth
// (48-67) landmark vertex on the mean face: eyelids, eye corners, lips and mouth corners.
std::vector<std::uint32_t> eye_mouth_vertices(const FaceModel& model, double radius_mm = 10.0);

// Per-vertex camera-frame distances between two posed meshes over `subset` (mm), appended.
void append_vertex_distances(std::span<const float> a, const RigidPose& pose_a,
                             std::span<const float> b, const RigidPose& pose_b,
                             std::span<const std::uint32_t> subset, std::vector<double>& out);

}  // namespace fb::cli
