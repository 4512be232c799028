// The wrinkle detail as geometry, for formats that carry no normal or displacement map a viewer
// applies (OBJ as most tools read it; issue 40 item 4): the face mesh is 2-3 mm between vertices,
// coarser than a wrinkle, so the triangles under the detail (and a ring around them) are
// subdivided at their edge midpoints, the UVs interpolated alike, and the vertices moved along
// their normals by the displacement map's heights (displace_mesh: umbrella smoothing over the
// rings either side of the displaced area's border).
//
// Midpoint (linear) subdivision, not Loop: the subdivided surface is the input's, so everywhere
// the map has no detail the output is exactly the undisplaced mesh, and every vertex's offset is
// its height. Neighbours of subdivided triangles are split into 2 or 3 (red-green refinement),
// so the mesh has no T-junctions and stays closed where the input was.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "algo/core/image.hpp"
#include "algo/core/result.hpp"
#include "algo/wrinkles/wrinkle_geometry.hpp"

namespace fb {

struct DetailMeshInput {
  std::span<const float> vertices;  // 3 floats per vertex, mm
  std::span<const std::uint32_t> triangles;
  std::span<const float> uvs;  // (u, v) pairs, v up, the layout the map is in
  std::span<const std::uint32_t> triangle_uvs;
  const FloatImage* displacement_mm = nullptr;  // row 0 at v = 1 (DetailMaps, the store's)
};

struct DetailMeshOptions {
  int levels = 2;           // midpoint subdivisions (2: edges of 0.6-0.8 mm, the map's texels)
  int margin_rings = 1;     // triangles this many edge-neighbours around the detail also refined
  float min_height_mm = 0;  // |height| above this marks a texel as detail
  DisplaceOptions smoothing;
};

struct DetailMesh {
  std::vector<float> undisplaced;  // the subdivided mesh: the input's surface
  std::vector<float> positions;    // displaced
  std::vector<std::uint32_t> triangles;
  std::vector<float> uvs;
  std::vector<std::uint32_t> triangle_uvs;
  std::vector<float> heights;  // per vertex, sampled from the map (before border smoothing)
  int refined_triangles = 0;   // input triangles subdivided in full
  // Vertex input_count + i is the midpoint of parents[i] (earlier vertices, in this order), so
  // any per-vertex quantity of the input follows the subdivision: interpolate_midpoints.
  std::vector<std::array<std::uint32_t, 2>> parents;
};

// Fails on a layout that does not fit the mesh, or an empty map.
Result<DetailMesh> subdivided_detail_mesh(const DetailMeshInput& in,
                                          const DetailMeshOptions& options = {});

// `values` (`dim` floats per input vertex) extended to the subdivided mesh's vertices: each
// midpoint the mean of its parents, as the positions were (bit for bit the same arithmetic).
std::vector<float> interpolate_midpoints(std::span<const float> values, int dim,
                                         std::span<const std::array<std::uint32_t, 2>> parents);

// Per vertex of a mesh with a per-corner UV layout: the map's height at its corners' UVs
// (sample_displacement), the mean over a seam vertex's corners; 0 for a vertex in no triangle.
std::vector<float> corner_mean_heights(const FloatImage& map,
                                       const std::vector<std::int32_t>& covered_triangle,
                                       std::size_t vertex_count,
                                       std::span<const std::uint32_t> triangles,
                                       std::span<const float> uvs,
                                       std::span<const std::uint32_t> triangle_uvs);

// The map's height at (u, v) (v up), bilinear over the texels the layout covers (texels
// outside every UV triangle hold no surface and are left out of the weights).
float sample_displacement(const FloatImage& map, const std::vector<std::int32_t>& covered_triangle,
                          float u, float v);

}  // namespace fb
