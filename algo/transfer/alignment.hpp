// Section V's alignment: before transfer the target is brought into the source's frame by the
// least-squares similarity (rotation, uniform scale, translation; Umeyama's SVD solution) over
// corresponding points, because each vertex's Q is a transformation in world axes: a jaw that
// opens about the source's X axis must open about the target's own.
#pragma once

#include <span>

#include <Eigen/Core>

#include "algo/core/result.hpp"
#include "algo/transfer/tent_mesh.hpp"

namespace fb {

struct Similarity {
  double scale = 1.0;
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::RowVector3d translation = Eigen::RowVector3d::Zero();

  Points apply(const Points& p) const;    // scale * R * p + t, per row
  Points inverse(const Points& p) const;  // R^T (p - t) / scale
};

// The similarity that takes `from` onto `to` (same row count; rows are corresponding points).
// With `subset` non-empty only those rows count (e.g. landmark vertices). Fails with fewer than
// three usable points or when they are (near) collinear.
Result<Similarity> align_similarity(const Points& from, const Points& to,
                                    std::span<const int> subset = {});

}  // namespace fb
