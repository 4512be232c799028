// Test meshes of another topology with known truth (eval transfer, bench transfer, tests): the
// face model's triangles split at centroids, re-triangulated (each quad's other diagonal) or
// decimated (half-edge collapses onto kept vertices). Every new vertex is a fixed blend of
// original vertices, so any shape of the model (an identity, an expression) has an exact
// counterpart on the remeshed topology: Remesh::apply.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "algo/transfer/tent_mesh.hpp"

namespace fb {

struct Remesh {
  std::vector<std::uint32_t> triangles;
  // Vertex i = sum_k weights[i][k] * original[sources[i][k]].
  std::vector<std::array<std::uint32_t, 3>> sources;
  std::vector<std::array<double, 3>> weights;

  int vertex_count() const { return static_cast<int>(sources.size()); }
  Points apply(const Points& original) const;
};

// Triangles whose corners are all < `region_end` split 1 -> 3 at their centroid, in index order,
// until the mesh has `max_vertices` vertices.
Remesh split_at_centroids(std::span<const std::uint32_t> triangles, int vertex_count,
                          int region_end, int max_vertices);

// Triangles 2k and 2k + 1 that share an edge (a quad split in two) re-split along the quad's
// other diagonal: same vertices, another triangulation.
Remesh flip_quad_diagonals(std::span<const std::uint32_t> triangles, int vertex_count);

// Interior vertices not in `keep` collapsed onto their nearest neighbour (link condition, no
// triangle turned over by more than 60 degrees) in passes of independent collapses, until at
// most `fraction` of the vertices remain or a pass collapses nothing.
Remesh decimate(std::span<const std::uint32_t> triangles, const Points& positions, double fraction,
                std::span<const std::uint32_t> keep);

}  // namespace fb
