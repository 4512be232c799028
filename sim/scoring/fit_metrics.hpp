// Error figures of eval fit beyond the mean vertex error: the eye and mouth region (where a
// refinement that follows holes and depth jumps shows first) and the capture QA rule.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

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

// Where a fit's vertex error lies (camera frame, mm, over `subset`): the mean offset of the
// fitted vertices from the truth, the mean error once that offset is taken out, and once the
// best rigid motion (Kabsch) is taken out: a fit that is right in shape but slid or turned on
// the face reads high in the first and low in the last.
struct VertexErrorParts {
  Eigen::Vector3d mean_offset_mm = Eigen::Vector3d::Zero();
  double after_translation_mm = 0;
  double after_rigid_mm = 0;
  double rigid_rotation_deg = 0;
  // Once the best similarity (rigid + one scale) is taken out, and that scale: a fit of the
  // right shape but the wrong size reads high after a rigid motion and low here. The scale is
  // the truth's size over the fit's.
  double after_similarity_mm = 0;
  double similarity_scale = 1;
  // Along the truth's surface normal and across it (with `triangles`; 0 without): depth can
  // only show the first.
  double normal_mm = 0;
  double tangential_mm = 0;
};
VertexErrorParts vertex_error_parts(std::span<const float> fitted, const RigidPose& pose_fitted,
                                    std::span<const float> truth, const RigidPose& pose_truth,
                                    std::span<const std::uint32_t> subset,
                                    std::span<const std::uint32_t> triangles = {});

}  // namespace fb::cli
