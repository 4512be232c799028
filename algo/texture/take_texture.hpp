// A take's texture end to end: the fitted mesh is placed on frame 0 from its 3D landmarks,
// followed through every frame by ICP against the depth, and the colour of up to `max_views`
// well-aligned frames, spread over the take, is blended into the atlas (texture_atlas.hpp).
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "algo/core/frame.hpp"
#include "algo/texture/mesh_alignment.hpp"
#include "algo/texture/texture_atlas.hpp"

namespace fb {

struct TakeTextureInput {
  std::span<const float> vertices;  // the fitted mesh, model frame
  std::span<const std::uint32_t> triangles;
  int region_vertices = 0;  // the first this many vertices are the face (alignment samples)
  std::span<const RgbdFrame> frames;
  // Landmark pairs for the start on frame 0: mesh points (model frame) and the capture's 3D
  // landmarks (frame 0's depth camera frame). Unused when `start` is given.
  std::span<const Eigen::Vector3d> landmarks_model;
  std::span<const Eigen::Vector3d> landmarks_camera;
  std::optional<RigidPose> start;  // camera_from_model of frame 0, when known
};

struct TakeTextureOptions {
  int max_views = 15;
  AlignOptions align;
  TextureOptions texture;
};

struct TakeTexture {
  TextureAtlas atlas;
  std::vector<RigidPose> poses;  // camera_from_model per frame (the last good one when lost)
  std::vector<AlignStats> alignment;
  std::vector<int> views;  // frames the colour came from
  int frames_aligned = 0;
};

Result<TakeTexture> texture_from_take(const TexelMap& map, const TakeTextureInput& input,
                                      const KinectRegistration& registration,
                                      const TakeTextureOptions& options = {});

}  // namespace fb
