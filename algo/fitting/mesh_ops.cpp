#include "algo/fitting/mesh_ops.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

#include <Eigen/Geometry>

namespace fb::fitting_detail {

Points to_points(std::span<const float> xyz) {
  const Eigen::Index n = static_cast<Eigen::Index>(xyz.size() / 3);
  Points p(n, 3);
  for (Eigen::Index i = 0; i < n; ++i)
    for (int d = 0; d < 3; ++d) p(i, d) = xyz[static_cast<std::size_t>(3 * i + d)];
  return p;
}

void from_points(const Points& p, std::vector<float>& xyz) {
  xyz.resize(static_cast<std::size_t>(p.rows()) * 3);
  for (Eigen::Index i = 0; i < p.rows(); ++i)
    for (int d = 0; d < 3; ++d)
      xyz[static_cast<std::size_t>(3 * i + d)] = static_cast<float>(p(i, d));
}

Points vertex_normals(const Points& v, std::span<const std::uint32_t> triangles) {
  Points n = Points::Zero(v.rows(), 3);
  for (std::size_t t = 0; t + 2 < triangles.size(); t += 3) {
    const auto a = triangles[t], b = triangles[t + 1], c = triangles[t + 2];
    const Eigen::Vector3d pa = v.row(a).transpose(), pb = v.row(b).transpose(),
                          pc = v.row(c).transpose();
    const Eigen::Vector3d fn = (pb - pa).cross(pc - pa);
    n.row(a) += fn.transpose();
    n.row(b) += fn.transpose();
    n.row(c) += fn.transpose();
  }
  for (Eigen::Index i = 0; i < n.rows(); ++i) {
    const double len = n.row(i).norm();
    if (len > 0) n.row(i) /= len;
  }
  return n;
}

Eigen::SparseMatrix<double> cotangent_laplacian(const Points& v,
                                                std::span<const std::uint32_t> triangles) {
  std::vector<Eigen::Triplet<double>> trip;
  trip.reserve(triangles.size() * 4);
  for (std::size_t t = 0; t + 2 < triangles.size(); t += 3) {
    const int idx[3] = {static_cast<int>(triangles[t]), static_cast<int>(triangles[t + 1]),
                        static_cast<int>(triangles[t + 2])};
    for (int k = 0; k < 3; ++k) {
      // Angle at corner k is opposite edge (k+1, k+2): contributes cot/2 to that edge.
      const int i = idx[(k + 1) % 3], j = idx[(k + 2) % 3], o = idx[k];
      const Eigen::Vector3d e1 = (v.row(i) - v.row(o)).transpose();
      const Eigen::Vector3d e2 = (v.row(j) - v.row(o)).transpose();
      const double s = e1.cross(e2).norm();
      const double cot = s > 1e-12 ? std::clamp(e1.dot(e2) / s, -10.0, 10.0) : 0.0;
      const double w = 0.5 * cot;
      trip.emplace_back(i, j, -w);
      trip.emplace_back(j, i, -w);
      trip.emplace_back(i, i, w);
      trip.emplace_back(j, j, w);
    }
  }
  Eigen::SparseMatrix<double> l(v.rows(), v.rows());
  l.setFromTriplets(trip.begin(), trip.end());
  return l;
}

std::vector<int> convex_hull(const std::vector<Eigen::Vector2d>& points) {
  std::vector<int> order(points.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](int a, int b) {
    return points[a].x() < points[b].x() ||
           (points[a].x() == points[b].x() && points[a].y() < points[b].y());
  });
  if (order.size() < 3) return order;
  auto cross = [&](int o, int a, int b) {
    const Eigen::Vector2d oa = points[a] - points[o], ob = points[b] - points[o];
    return oa.x() * ob.y() - oa.y() * ob.x();
  };
  std::vector<int> hull(2 * order.size());
  std::size_t k = 0;
  for (int i : order) {
    while (k >= 2 && cross(hull[k - 2], hull[k - 1], i) <= 0) --k;
    hull[k++] = i;
  }
  for (std::size_t i = order.size() - 1, lower = k + 1; i-- > 0;) {
    const int p = order[i];
    while (k >= lower && cross(hull[k - 2], hull[k - 1], p) <= 0) --k;
    hull[k++] = p;
  }
  hull.resize(k - 1);
  return hull;
}

}  // namespace fb::fitting_detail
