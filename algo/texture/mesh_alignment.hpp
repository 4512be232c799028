// Puts a fitted mesh (model frame) where the subject's face is in each depth frame of a take:
// a rigid start from 3D landmark pairs (Kabsch), then projective point-to-plane ICP of the
// mesh's camera-facing vertices against the frame's depth, frame after frame. The stored
// session keeps meshes in the model frame without the pose they were fitted at, so the host
// finds it again here; going through every frame keeps a head turn's steps small for ICP.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "algo/core/camera_model.hpp"
#include "algo/core/image.hpp"
#include "algo/core/mesh_normals.hpp"
#include "algo/core/result.hpp"

namespace fb {

// camera_from_model minimising sum |R m_i + t - c_i|^2 (no scale). Needs 3 pairs or more, not
// collinear.
Result<RigidPose> rigid_from_pairs(std::span<const Eigen::Vector3d> model,
                                   std::span<const Eigen::Vector3d> camera);

struct AlignOptions {
  int iterations = 15;
  float first_gate_mm = 20.0f;  // residual cut-off of the first iteration (a rough start)
  float gate_mm = 4.0f;         // ... shrinking to this (depth noise plus fit error)
  int max_samples = 5000;       // mesh vertices used (evenly spread over the face)
  // A frame after an aligned one starts from that frame's pose moved on by the last step
  // (constant velocity): a short schedule from a tighter gate suffices there.
  int tracking_iterations = 5;
  float tracking_first_gate_mm = 8.0f;
  // After the schedule, up to this many more steps at gate_mm until a step is under both
  // settle limits (a frame whose start was further off than usual catches up).
  int settle_iterations = 10;
  float settle_deg = 0.05f;
  float settle_mm = 0.05f;
  float min_facing = 0.3f;  // cos of the angle between a vertex normal and the view ray
};

struct AlignStats {
  int samples = 0;  // camera-facing sample vertices inside the image
  int inliers = 0;  // ... with a depth sample within the gate
  float rms_mm = 0.0f;
  bool ok() const { return inliers >= 200 && inliers * 2 >= samples; }
};

// Every k-th vertex of the first `region_vertices` (the face region), at most max_samples.
std::vector<std::uint32_t> alignment_samples(int region_vertices, int max_samples);

// Refines `camera_from_model` in place against `depth_mm` (depth camera image, 0 = none).
AlignStats align_to_depth(std::span<const float> vertices, std::span<const float> normals,
                          std::span<const std::uint32_t> samples, const DepthImage& depth_mm,
                          const PinholeIntrinsics& intrinsics, RigidPose& camera_from_model,
                          const AlignOptions& options = {});

}  // namespace fb
