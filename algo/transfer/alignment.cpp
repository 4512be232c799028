#include "algo/transfer/alignment.hpp"

#include <string>

#include <Eigen/Geometry>
#include <Eigen/SVD>

namespace fb {

Points Similarity::apply(const Points& p) const {
  return ((scale * p) * rotation.transpose()).rowwise() + translation;
}

Points Similarity::inverse(const Points& p) const {
  return ((p.rowwise() - translation) * rotation) / scale;
}

Result<Similarity> align_similarity(const Points& from, const Points& to,
                                    std::span<const int> subset) {
  if (from.rows() != to.rows())
    return fail("alignment: " + std::to_string(from.rows()) + " points against " +
                std::to_string(to.rows()));
  const Eigen::Index n = subset.empty() ? from.rows() : static_cast<Eigen::Index>(subset.size());
  Eigen::Matrix3Xd a(3, n), b(3, n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const Eigen::Index r = subset.empty() ? i : subset[static_cast<std::size_t>(i)];
    if (r < 0 || r >= from.rows()) return fail("alignment: point index out of range");
    a.col(i) = from.row(r).transpose();
    b.col(i) = to.row(r).transpose();
  }
  if (n < 3) return fail("alignment needs at least 3 corresponding points");
  const Eigen::Matrix3Xd centred = a.colwise() - a.rowwise().mean();
  const Eigen::JacobiSVD<Eigen::Matrix3Xd> svd(centred);
  const Eigen::Vector3d sv = svd.singularValues();
  if (!(sv[1] > 1e-9 * std::max(sv[0], 1e-300)))
    return fail("alignment: the corresponding points are collinear");
  const Eigen::Matrix4d t = Eigen::umeyama(a, b, true);
  Similarity s;
  s.scale = t.block<3, 3>(0, 0).col(0).norm();
  s.rotation = t.block<3, 3>(0, 0) / s.scale;
  s.translation = t.block<3, 1>(0, 3).transpose();
  return s;
}

}  // namespace fb
