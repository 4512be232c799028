// What engines need beyond positions: per-vertex normals and the UV layout, and the vertex split
// that formats with one index per vertex (glTF) need where a vertex has several UVs (a seam).
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "algo/core/mesh_normals.hpp"

namespace fb {

// The face model's UV layout for a mesh with its topology (FaceModel::uvs / triangle_uvs):
// (u, v) pairs with v up (OBJ convention), and the UV index of each triangle corner.
struct MeshUvs {
  std::vector<float> uvs;
  std::vector<std::uint32_t> triangle_uvs;
  bool empty() const { return uvs.empty(); }
  // True when the layout fits `triangles` (one UV index per corner, all in range).
  bool fits(std::span<const std::uint32_t> triangles) const;
};

// vertex_normals(): algo/core/mesh_normals.hpp.

// One output vertex per distinct (vertex, UV) corner pair, in order of first use.
struct SplitMesh {
  std::vector<std::uint32_t> source_vertex;  // output vertex -> input vertex
  std::vector<std::uint32_t> uv_index;       // output vertex -> MeshUvs::uvs pair
  std::vector<std::uint32_t> triangles;      // re-indexed to the output vertices
};
SplitMesh split_seams(std::span<const std::uint32_t> triangles, const MeshUvs& uvs);

}  // namespace fb
