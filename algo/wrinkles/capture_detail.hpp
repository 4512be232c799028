// One stored expression capture's wrinkle detail in the face model's UV layout (issue 40 items
// 4 and 5; what `facebooth wrinkles` runs per capture). The colour frame is pulled into the depth
// camera's pixel grid through the unit's registration at the fitted mesh's depth (the mesh,
// posed by its landmarks, says where the skin is), so one pinhole camera (the depth camera's)
// ties the image, its 68 landmarks (the mesh's landmark vertices projected) and the mesh
// together; then wrinkle_detail() on that image and detail_maps() over the mesh.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "algo/core/camera_model.hpp"
#include "algo/core/image.hpp"
#include "algo/core/result.hpp"
#include "algo/sensor/kinect_calibration.hpp"
#include "algo/texture/texel_map.hpp"
#include "algo/wrinkles/wrinkle_detail.hpp"
#include "algo/wrinkles/wrinkle_geometry.hpp"

namespace fb {

struct CaptureDetail;

struct CaptureDetailInput {
  const ColorImage* color = nullptr;  // the capture's frontal colour frame (colour camera)
  std::span<const float> vertices;    // the fitted mesh, model frame, 3 floats per vertex
  std::span<const std::uint32_t> triangles;
  RigidPose depth_from_model;  // where the mesh is in the depth camera
  std::array<std::uint32_t, 68> landmark_vertices{};
  // The UV layout the maps are made in (TexelMap made from the same uvs / triangle_uvs).
  const TexelMap* map = nullptr;
  std::span<const float> uvs;
  std::span<const std::uint32_t> triangle_uvs;
  // The subject's neutral capture's result (its luminance and mesh in the depth grid): the
  // expression's luminance is divided by it, warped through the two meshes (the expression
  // ratio image, WrinkleDetailOptions::ratio_image). Null for the neutral itself.
  const CaptureDetail* neutral = nullptr;
};

struct CaptureDetailOptions {
  WrinkleDetailOptions detail;
  // feather_heights() again before the maps, beyond WrinkleDetailOptions::feather_px (0 = off).
  int feather_px = 0;
  // Regions given by hand in the colour frame's pixels (`facebooth wrinkles --region`): each
  // becomes the box of the depth-grid pixels whose colour lies inside it (at the mesh's depth),
  // and goes to detail.given_regions (instead of the detected ones unless
  // detail.given_alongside).
  std::vector<PixelRect> color_regions;
};

struct CaptureDetail {
  FloatImage luminance;  // the colour frame's luma in the depth camera's grid, 0..1
  std::array<Eigen::Vector2d, 68> landmarks;     // in that grid
  std::vector<Eigen::Vector3f> camera_vertices;  // the mesh in the depth camera (mm)
  WrinkleDetail detail;                          // regions and heights in that grid
  DetailMaps maps;                               // in the UV layout
};

Result<CaptureDetail> capture_detail(const CaptureDetailInput& input,
                                     const KinectRegistration& registration,
                                     std::span<const WrinkleExemplar> exemplars,
                                     const CaptureDetailOptions& options = {});

}  // namespace fb
