// Locates a UV in a mesh's UV layout (the face model's, in tests): a grid of buckets over the UV
// triangles; the triangle holding (u, v) and its barycentric weights there.
#pragma once

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

namespace fb::test {

class UvLocator {
 public:
  // `uvs`: (u, v) pairs; `triangle_uvs`: the UV index of each triangle corner. Both are kept by
  // reference.
  UvLocator(const std::vector<float>& uvs, const std::vector<std::uint32_t>& triangle_uvs)
      : uvs_(uvs), tri_(triangle_uvs), cells_(kCells * kCells) {
    for (std::size_t t = 0; t < tri_.size() / 3; ++t) {
      float lo[2] = {1, 1}, hi[2] = {0, 0};
      for (int k = 0; k < 3; ++k)
        for (int d = 0; d < 2; ++d) {
          lo[d] = std::min(lo[d], uvs_[2 * tri_[3 * t + k] + d]);
          hi[d] = std::max(hi[d], uvs_[2 * tri_[3 * t + k] + d]);
        }
      for (int y = cell(lo[1]); y <= cell(hi[1]); ++y)
        for (int x = cell(lo[0]); x <= cell(hi[0]); ++x)
          cells_[static_cast<std::size_t>(y * kCells + x)].push_back(static_cast<int>(t));
    }
  }
  // The triangle and barycentric weights at (u, v), or triangle -1; a weight may be as low as
  // -tolerance (points on an edge, UVs rounded to float).
  std::pair<int, Eigen::Vector3d> find(double u, double v, double tolerance = 1e-5) const {
    for (int t : cells_[static_cast<std::size_t>(cell(v) * kCells + cell(u))]) {
      Eigen::Vector2d q[3];
      for (int k = 0; k < 3; ++k) q[k] = {uvs_[2 * tri_[3 * t + k]], uvs_[2 * tri_[3 * t + k] + 1]};
      Eigen::Matrix2d m;
      m << q[1] - q[0], q[2] - q[0];
      if (std::abs(m.determinant()) < 1e-14) continue;
      const Eigen::Vector2d b = m.inverse() * (Eigen::Vector2d(u, v) - q[0]);
      if (b.x() >= -tolerance && b.y() >= -tolerance && b.x() + b.y() <= 1 + tolerance)
        return {t, Eigen::Vector3d(1 - b.x() - b.y(), b.x(), b.y())};
    }
    return {-1, Eigen::Vector3d::Zero()};
  }

 private:
  static constexpr int kCells = 256;
  static int cell(double x) { return std::clamp(static_cast<int>(x * kCells), 0, kCells - 1); }
  const std::vector<float>& uvs_;
  const std::vector<std::uint32_t>& tri_;
  std::vector<std::vector<int>> cells_;
};

}  // namespace fb::test
