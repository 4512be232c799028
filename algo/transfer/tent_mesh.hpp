// Vertex-tent coordinates (Song et al., "A generic framework for efficient 2D and 3D facial
// expression analogy", section IV): a vertex v0, its one ring v1..vn and an apex v_{n+1} on the
// vertex normal encode the local geometry as the 3 x (n+1) matrix
//   w = [v1 - v0, ..., vn - v0, v_{n+1} - v0],
// and a deformation of that tent as the 3x3 Q with Q w = w' (least squares: eq. 2,
// Q = w' w^T (w w^T)^-1). Works on any polygon mesh (triangles, quads, mixed): the ring is the
// vertices that share an edge with v0.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "algo/core/result.hpp"

namespace fb {

// One vertex per row, millimetres (or any unit: VTC is scale-free).
using Points = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

Points points_from_floats(std::span<const float> xyz);  // 3 floats per vertex
std::vector<float> floats_from_points(const Points& points);

// A polygon mesh's faces: face f has the vertices indices[offsets[f] .. offsets[f + 1]).
struct PolygonFaces {
  int vertex_count = 0;
  std::vector<std::uint32_t> indices;
  std::vector<std::uint32_t> offsets{0};

  int face_count() const { return static_cast<int>(offsets.size()) - 1; }
};

// Triangles (3 indices each) or quads (4 each) as PolygonFaces. Fails on an index out of range,
// a size that is not a multiple of the corner count or a face that repeats a vertex.
Result<PolygonFaces> faces_of(int vertex_count, std::span<const std::uint32_t> indices,
                              int corners);

// The faces as triangles (polygons fanned from their first corner), 3 indices each.
std::vector<std::uint32_t> fan_triangles(const PolygonFaces& faces);

// Edge neighbours of every vertex (sorted, compressed rows) and the mesh's connected components.
struct TentTopology {
  int vertex_count = 0;
  std::vector<std::uint32_t> ring_offsets;  // vertex_count + 1
  std::vector<std::uint32_t> rings;
  std::vector<int> component;  // per vertex; isolated vertices (no face) get their own
  int component_count = 0;
  PolygonFaces faces;

  std::span<const std::uint32_t> ring(int v) const {
    return {rings.data() + ring_offsets[static_cast<std::size_t>(v)],
            rings.data() + ring_offsets[static_cast<std::size_t>(v) + 1]};
  }
};

TentTopology tent_topology(const PolygonFaces& faces);

// Area-weighted unit vertex normals (Newell's normal of each polygon, summed at its corners);
// (0, 0, 1) where no face has area.
Points vertex_normals(const PolygonFaces& faces, const Points& points);

// Each vertex's share of the surface: 1/k of the area of every k-gon it is a corner of.
std::vector<double> vertex_areas(const PolygonFaces& faces, const Points& points);

// The apex of every tent: v0 + normal * (mean length of v0's ring edges), so that the tent's
// height stretches with the surface as the third triangle vertex of Sumner and Popovic does.
Points tent_apexes(const TentTopology& topology, const Points& points);

// w of vertex v (3 x (ring + 1)); `apexes` from tent_apexes() of the same points.
Eigen::Matrix3Xd tent_coordinates(const TentTopology& topology, const Points& points,
                                  const Points& apexes, int v);

// w^T (w w^T)^-1 ((n + 1) x 3): Q = w' * this. A degenerate tent (w w^T near singular, e.g. a
// vertex with no ring) gets a pseudo-inverse, so its Q keeps only what the tent can say.
Eigen::MatrixX3d tent_inverse(const Eigen::Matrix3Xd& w);

}  // namespace fb
