// Image-shaped objects of the fusion pipeline: the input depth pyramid with vertex and normal
// maps, and the ray-cast model view the tracker aligns against. All buffers are allocated once
// in allocate() and reused for every frame.
#pragma once

#include <array>

#include <Eigen/Core>

#include "algo/core/image.hpp"
#include "algo/core/pixel_rect.hpp"
#include "algo/core/rigid_pose.hpp"
#include "algo/fusion/fusion_types.hpp"

namespace fb {

inline constexpr int kPyramidLevels = 3;

// Float pinhole intrinsics of one pyramid level (hot loops use float).
struct LevelIntrinsics {
  int width = 0;
  int height = 0;
  float fx = 0, fy = 0, cx = 0, cy = 0;

  static LevelIntrinsics from(const PinholeIntrinsics& k) {
    return {k.width,
            k.height,
            static_cast<float>(k.fx),
            static_cast<float>(k.fy),
            static_cast<float>(k.cx),
            static_cast<float>(k.cy)};
  }
  // 2x2 block averaging: the centre of block (u1) is at u0 = 2 u1 + 0.5.
  LevelIntrinsics averaged_half() const {
    return {width / 2, height / 2, fx * 0.5f, fy * 0.5f, (cx - 0.5f) * 0.5f, (cy - 0.5f) * 0.5f};
  }
  // Plain subsampling: pixel u1 is pixel u0 = 2 u1.
  LevelIntrinsics subsampled_half() const {
    return {width / 2, height / 2, fx * 0.5f, fy * 0.5f, cx * 0.5f, cy * 0.5f};
  }
};

struct MapLevel {
  LevelIntrinsics k;
  PixelRect box;                    // the face box's rectangle on this level
  Image<float> depth;               // mm, 0 = invalid
  Image<Eigen::Vector3f> vertices;  // camera frame; z == 0 marks invalid
  Image<Eigen::Vector3f> normals;   // camera frame, unit; zero where invalid

  void allocate(const LevelIntrinsics& intrinsics, const PixelRect& face_rect);
  // Moves the box without reallocating: what the old box held (and a 1 px rim, which filters
  // and normals read) is cleared, so nothing stale is read from outside the new box.
  void move_box(const PixelRect& face_rect);
};

// The preprocessed input frame: raw depth (gated, float) plus 3 filtered levels.
struct DepthPyramid {
  Image<float> raw;    // level-0 raw depth in mm, inside the face box only
  Image<float> fused;  // what the integrator fuses: raw (or filtered) without grazing pixels
  std::array<MapLevel, kPyramidLevels> levels;
  int valid_pixels = 0;  // valid raw pixels inside the face box

  void allocate(const PinholeIntrinsics& intrinsics, const PixelRect& face_rect);
  void move_box(const PixelRect& face_rect);  // level-0 box; every level and raw/fused follow
};

// The ray-cast model view (vertices and normals in the frame of the camera it was cast from).
// levels[j] has the resolution of pyramid level first_level + j: levels[0] is ray-cast, the
// others are subsampled from it. Input level l associates with levels[max(0, l - first_level)].
struct ModelView {
  std::array<MapLevel, kPyramidLevels> levels;
  int first_level = 0;
  RigidPoseF world_from_camera;  // the pose it was cast from
  bool valid = false;

  void allocate(const PinholeIntrinsics& intrinsics, const PixelRect& face_rect, int first);
  void move_box(const PixelRect& face_rect);  // level-0 box, as DepthPyramid::move_box
  const MapLevel& for_input_level(int l) const {
    return levels[l > first_level ? l - first_level : 0];
  }
};

}  // namespace fb
