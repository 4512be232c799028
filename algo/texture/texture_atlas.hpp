// The subject's colour texture in the face model's UV layout, from a take's registered colour
// frames (FaceWarehouse captures colour with every expression; so does the booth):
//  1. every texel's surface point is posed into each chosen frame (the mesh aligned to that
//     frame, mesh_alignment.hpp), tested for visibility (the mesh's own z-buffer in the depth
//     camera, and the measured depth: a hand in front hides it, the wall behind means the mesh's
//     silhouette is off) and mapped into the colour image
//     through the unit's registration;
//  2. the frames' lighting is estimated and divided out (per frame and channel, shading =
//     l . [1, n] with the fitted mesh's normals, alternating with the albedo), so a texel seen
//     from the side is not darker than one seen from the front; the overall level stays the
//     frames' mean, since absolute albedo is not observable with an unknown exposure;
//  3. views are blended per texel with weight (facing cosine)^2 and texels no view saw are
//     filled by push-pull (atlas_fill.hpp).
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "algo/core/camera_model.hpp"
#include "algo/core/image.hpp"
#include "algo/core/result.hpp"
#include "algo/sensor/kinect_calibration.hpp"
#include "algo/texture/texel_map.hpp"

namespace fb {

// The fitted mesh in its model frame.
struct TextureMesh {
  std::span<const float> vertices;  // 3 per vertex, mm
  std::span<const float> normals;   // 3 per vertex, unit
  std::span<const std::uint32_t> triangles;
};

// One frame of the take: its colour and depth images and where the mesh is in it.
struct TextureView {
  const ColorImage* color = nullptr;
  const DepthImage* depth = nullptr;  // may be null: no occluder test
  RigidPose camera_from_model;        // depth camera frame
};

struct TextureOptions {
  float min_facing = 0.2f;     // cos of the view angle below which a view is not used
  float visibility_mm = 5.0f;  // a texel this far behind the mesh's own z-buffer is hidden
  float occluder_mm = 20.0f;   // measured depth this far from the texel (or none): not seen
  float clip_level = 250.0f;   // a sample with a channel this bright is clipped
  float weight_power = 2.0f;   // a view's weight: ((cos - min_facing) / (1 - min_facing))^power
  bool delight = true;
  int lighting_stride = 4;  // texels used for the lighting estimate: every n-th in x and y
  int lighting_iterations = 8;
};

struct TextureReport {
  int views = 0;
  int covered_texels = 0;   // texels the UV layout maps to the surface
  int observed_texels = 0;  // ... that at least one view saw
  int clipped_texels = 0;   // ... that every view saw over-exposed (a channel at clip_level)
  // Per view and channel: the shading l0 + l . n divided out (identity when not de-lit).
  std::vector<std::array<Eigen::Vector4f, 3>> lighting;
};

struct TextureAtlas {
  ColorImage image;             // size x size, sRGB-like 8 bit as the camera delivered it
  Image<float> weight;          // per texel: summed view weights (0 = filled, not observed)
  Image<std::uint8_t> clipped;  // 1 where every view was over-exposed: the colour is a bound
  TextureReport report;
};

Result<TextureAtlas> build_texture_atlas(const TexelMap& map, const TextureMesh& mesh,
                                         std::span<const TextureView> views,
                                         const KinectRegistration& registration,
                                         const TextureOptions& options = {});

}  // namespace fb
