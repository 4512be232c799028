// Correspondence between faces of different topology (seed 002, section V): both neutrals
// aligned by corresponding feature points (a similarity, alignment.hpp), projected onto a
// cylinder about the vertical axis, the cylinder plane parameterised by the Delaunay
// triangulation of the feature points and the four corners of each mesh's bounding box, and
// every target vertex carried through its parameterisation triangle (same barycentric
// coordinates in the source's) onto the source's cylindrical mesh.
//
// Unlike the paper, which resamples the target at the source's vertices and deletes what does
// not match, the target keeps its own topology: each target vertex gets a point on the source
// surface, the source's per-vertex transformations are blended there, and the VTC solve runs on
// the target's own tents. A vertex with no source point (outside the source's extent) keeps its
// shape (identity transformation, no motion).
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "algo/core/result.hpp"
#include "algo/transfer/alignment.hpp"
#include "algo/transfer/tent_mesh.hpp"
#include "algo/transfer/vtc_transfer.hpp"

namespace fb {

struct SurfacePoint {
  std::array<std::uint32_t, 3> corners{};  // a source triangle
  Eigen::Vector3d weights = Eigen::Vector3d::Zero();
  bool matched = false;
};

struct Correspondence {
  std::vector<SurfacePoint> points;  // one per target vertex
  int unmatched = 0;
  Similarity alignment;  // target -> source frame, from the feature points
};

// `features`: corresponding 3D points on each neutral (e.g. the 68 landmarks), same count, at
// least 4 and not collinear. Triangles are the meshes' (3 indices each).
Result<Correspondence> find_correspondence(const Points& source_neutral,
                                           std::span<const std::uint32_t> source_triangles,
                                           const Points& source_features,
                                           const Points& target_neutral,
                                           const Points& target_features);

// The source's per-vertex transformations (or any per-vertex values) at the target's vertices:
// barycentric blends; unmatched vertices get the identity (or zero motion).
Transformations map_transformations(const Correspondence& c, const Transformations& source);
Points map_points(const Correspondence& c, const Points& source);

// Delaunay triangulation of 2D points (Bowyer-Watson; meant for tens to hundreds of points):
// 3 indices per triangle, counter-clockwise.
std::vector<std::uint32_t> delaunay(const std::vector<Eigen::Vector2d>& points);

}  // namespace fb
