// The synthesised wrinkle heights on the face (seed 004, end of section 3.3; issue 40 item 4):
// the mesh displaced along its normals, smoothed where displaced skin meets undisplaced skin;
// and, since the face mesh is 2-3 mm between vertices (coarser than a wrinkle), the detail as a
// displacement map and a tangent-space normal map in the face model's UV layout.
//
// Both read the height image through the expression frame's camera: a mesh point (model frame)
// is placed by camera_from_model and projected with the colour camera's intrinsics; only points
// the camera sees (the front-most surface at their pixel) inside the synthesis domain take a
// height, everything else 0.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "algo/core/camera_model.hpp"
#include "algo/core/image.hpp"
#include "algo/core/result.hpp"
#include "algo/texture/texel_map.hpp"
#include "algo/wrinkles/exemplar.hpp"

namespace fb {

struct HeightView {
  const FloatImage* height_mm = nullptr;        // the synthesis's output
  const Image<std::uint8_t>* domain = nullptr;  // 1 where it synthesised
  RigidPose camera_from_model;
  PinholeIntrinsics intrinsics;
  double visibility_tolerance_mm = 3.0;  // a point this far behind the front-most is hidden
};

// The height (mm) each vertex sees; 0 when hidden or outside the domain.
std::vector<float> vertex_heights(std::span<const float> vertices,
                                  std::span<const std::uint32_t> triangles, const HeightView& view);

struct DisplaceOptions {
  // Laplacian (umbrella) smoothing of the heights over this many rings either side of where
  // displaced vertices meet undisplaced ones, this many iterations.
  int border_rings = 2;
  int smoothing_iterations = 4;
};

// The mesh (3 floats per vertex) moved along its vertex normals by `heights`, the heights first
// smoothed at the borders of the displaced area.
std::vector<float> displace_mesh(std::span<const float> vertices,
                                 std::span<const std::uint32_t> triangles,
                                 std::span<const float> heights,
                                 const DisplaceOptions& options = {});

struct DetailMaps {
  FloatImage displacement_mm;  // per texel, along the normal; 0 where nothing was synthesised
  ColorImage normal_map;       // tangent space, (0.5, 0.5, 1) flat: x along +u, y along +v
  int texels_with_detail = 0;
};

// The detail in a UV layout: every texel's surface point (`map`, over `vertices`) looked up in
// the height image; `uvs` and `triangle_uvs` the layout `map` was made from (the tangent frame
// of each triangle comes from them).
Result<DetailMaps> detail_maps(const TexelMap& map, std::span<const float> uvs,
                               std::span<const std::uint32_t> triangle_uvs,
                               std::span<const float> vertices,
                               std::span<const std::uint32_t> triangles, const HeightView& view);

}  // namespace fb
