#include "algo/transfer/tent_mesh.hpp"

#include <algorithm>
#include <numeric>
#include <string>

#include <Eigen/Eigenvalues>

namespace fb {

Points points_from_floats(std::span<const float> xyz) {
  const Eigen::Index n = static_cast<Eigen::Index>(xyz.size() / 3);
  Points p(n, 3);
  for (Eigen::Index i = 0; i < n; ++i)
    for (int d = 0; d < 3; ++d) p(i, d) = xyz[static_cast<std::size_t>(3 * i + d)];
  return p;
}

std::vector<float> floats_from_points(const Points& points) {
  std::vector<float> out(static_cast<std::size_t>(points.rows()) * 3);
  for (Eigen::Index i = 0; i < points.rows(); ++i)
    for (int d = 0; d < 3; ++d) out[static_cast<std::size_t>(3 * i + d)] = float(points(i, d));
  return out;
}

Result<PolygonFaces> faces_of(int vertex_count, std::span<const std::uint32_t> indices,
                              int corners) {
  if (corners < 3) return fail("faces need at least 3 corners");
  if (indices.size() % static_cast<std::size_t>(corners) != 0)
    return fail("face indices: " + std::to_string(indices.size()) + " is not a multiple of " +
                std::to_string(corners));
  PolygonFaces f;
  f.vertex_count = vertex_count;
  f.indices.assign(indices.begin(), indices.end());
  for (std::size_t start = 0; start < indices.size(); start += static_cast<std::size_t>(corners)) {
    for (int k = 0; k < corners; ++k) {
      const auto v = indices[start + static_cast<std::size_t>(k)];
      if (v >= static_cast<std::uint32_t>(vertex_count))
        return fail("face " + std::to_string(f.face_count()) + " uses vertex " + std::to_string(v) +
                    " of a mesh with " + std::to_string(vertex_count));
      for (int m = 0; m < k; ++m)
        if (indices[start + static_cast<std::size_t>(m)] == v)
          return fail("face " + std::to_string(f.face_count()) + " repeats vertex " +
                      std::to_string(v));
    }
    f.offsets.push_back(static_cast<std::uint32_t>(start) + static_cast<std::uint32_t>(corners));
  }
  return f;
}

std::vector<std::uint32_t> fan_triangles(const PolygonFaces& faces) {
  std::vector<std::uint32_t> out;
  for (int f = 0; f < faces.face_count(); ++f) {
    const std::uint32_t b = faces.offsets[static_cast<std::size_t>(f)];
    const std::uint32_t e = faces.offsets[static_cast<std::size_t>(f) + 1];
    for (std::uint32_t k = b + 1; k + 1 < e; ++k)
      out.insert(out.end(), {faces.indices[b], faces.indices[k], faces.indices[k + 1]});
  }
  return out;
}

namespace {

int find_root(std::vector<int>& parent, int v) {
  while (parent[static_cast<std::size_t>(v)] != v) {
    parent[static_cast<std::size_t>(v)] = parent[static_cast<std::size_t>(parent[v])];
    v = parent[static_cast<std::size_t>(v)];
  }
  return v;
}

void label_components(TentTopology& t) {
  std::vector<int> parent(static_cast<std::size_t>(t.vertex_count));
  std::iota(parent.begin(), parent.end(), 0);
  for (int v = 0; v < t.vertex_count; ++v)
    for (std::uint32_t u : t.ring(v))
      parent[static_cast<std::size_t>(find_root(parent, v))] = find_root(parent, int(u));
  std::vector<int> label(static_cast<std::size_t>(t.vertex_count), -1);
  t.component.assign(static_cast<std::size_t>(t.vertex_count), 0);
  t.component_count = 0;
  for (int v = 0; v < t.vertex_count; ++v) {
    int& l = label[static_cast<std::size_t>(find_root(parent, v))];
    if (l < 0) l = t.component_count++;
    t.component[static_cast<std::size_t>(v)] = l;
  }
}

}  // namespace

TentTopology tent_topology(const PolygonFaces& faces) {
  TentTopology t;
  t.vertex_count = faces.vertex_count;
  t.faces = faces;
  std::vector<std::vector<std::uint32_t>> rings(static_cast<std::size_t>(faces.vertex_count));
  for (int f = 0; f < faces.face_count(); ++f) {
    const std::uint32_t b = faces.offsets[static_cast<std::size_t>(f)];
    const std::uint32_t e = faces.offsets[static_cast<std::size_t>(f) + 1];
    for (std::uint32_t k = b; k < e; ++k) {
      const std::uint32_t u = faces.indices[k], w = faces.indices[k + 1 < e ? k + 1 : b];
      rings[u].push_back(w);
      rings[w].push_back(u);
    }
  }
  t.ring_offsets.push_back(0);
  for (auto& r : rings) {
    std::sort(r.begin(), r.end());
    r.erase(std::unique(r.begin(), r.end()), r.end());
    t.rings.insert(t.rings.end(), r.begin(), r.end());
    t.ring_offsets.push_back(static_cast<std::uint32_t>(t.rings.size()));
  }
  label_components(t);
  return t;
}

Points vertex_normals(const PolygonFaces& faces, const Points& points) {
  Points sum = Points::Zero(points.rows(), 3);
  for (int f = 0; f < faces.face_count(); ++f) {
    const std::uint32_t b = faces.offsets[static_cast<std::size_t>(f)];
    const std::uint32_t e = faces.offsets[static_cast<std::size_t>(f) + 1];
    // Newell: twice the (vector) area of a planar or near-planar polygon.
    Eigen::RowVector3d n = Eigen::RowVector3d::Zero();
    for (std::uint32_t k = b; k < e; ++k) {
      const Eigen::RowVector3d p = points.row(faces.indices[k]);
      const Eigen::RowVector3d q = points.row(faces.indices[k + 1 < e ? k + 1 : b]);
      n += p.cross(q);
    }
    for (std::uint32_t k = b; k < e; ++k) sum.row(faces.indices[k]) += n;
  }
  for (Eigen::Index v = 0; v < sum.rows(); ++v) {
    const double len = sum.row(v).norm();
    if (len > 0)
      sum.row(v) /= len;
    else
      sum.row(v) = Eigen::RowVector3d(0, 0, 1);
  }
  return sum;
}

std::vector<double> vertex_areas(const PolygonFaces& faces, const Points& points) {
  std::vector<double> area(static_cast<std::size_t>(points.rows()), 0.0);
  for (int f = 0; f < faces.face_count(); ++f) {
    const std::uint32_t b = faces.offsets[static_cast<std::size_t>(f)];
    const std::uint32_t e = faces.offsets[static_cast<std::size_t>(f) + 1];
    Eigen::RowVector3d n = Eigen::RowVector3d::Zero();
    for (std::uint32_t k = b; k < e; ++k)
      n += Eigen::RowVector3d(points.row(faces.indices[k]))
               .cross(Eigen::RowVector3d(points.row(faces.indices[k + 1 < e ? k + 1 : b])));
    for (std::uint32_t k = b; k < e; ++k) area[faces.indices[k]] += n.norm() / 2 / (e - b);
  }
  return area;
}

Points tent_apexes(const TentTopology& topology, const Points& points) {
  const Points normals = vertex_normals(topology.faces, points);
  Points apex = points;
  for (int v = 0; v < topology.vertex_count; ++v) {
    const auto ring = topology.ring(v);
    if (ring.empty()) continue;
    double length = 0;
    for (std::uint32_t u : ring) length += (points.row(u) - points.row(v)).norm();
    apex.row(v) += normals.row(v) * (length / static_cast<double>(ring.size()));
  }
  return apex;
}

Eigen::Matrix3Xd tent_coordinates(const TentTopology& topology, const Points& points,
                                  const Points& apexes, int v) {
  const auto ring = topology.ring(v);
  Eigen::Matrix3Xd w(3, static_cast<Eigen::Index>(ring.size()) + 1);
  for (std::size_t j = 0; j < ring.size(); ++j)
    w.col(static_cast<Eigen::Index>(j)) = (points.row(ring[j]) - points.row(v)).transpose();
  w.col(w.cols() - 1) = (apexes.row(v) - points.row(v)).transpose();
  return w;
}

Eigen::MatrixX3d tent_inverse(const Eigen::Matrix3Xd& w) {
  const Eigen::Matrix3d gram = w * w.transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(gram);
  const Eigen::Vector3d lambda = eig.eigenvalues();
  const double floor = 1e-12 * std::max(lambda.maxCoeff(), 1e-300);
  Eigen::Vector3d inv;
  for (int k = 0; k < 3; ++k) inv[k] = lambda[k] > floor ? 1.0 / lambda[k] : 0.0;
  const Eigen::Matrix3d gram_inv =
      eig.eigenvectors() * inv.asDiagonal() * eig.eigenvectors().transpose();
  return w.transpose() * gram_inv;
}

}  // namespace fb
