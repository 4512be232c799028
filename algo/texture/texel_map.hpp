// Which surface point every texel of a UV layout shows: for each texel centre inside a UV
// triangle, the triangle and the barycentric weights of its corners. Built once per layout and
// atlas size; the atlas builder then only evaluates the mesh at those points.
//
// Convention (the OBJ one, kept by the face model's asset): u right, v up, (0, 0) the image's
// bottom-left corner, the layout in one [0, 1] square (FaceModel::atlas_uvs()). Texel (x, y)
// of a width x height atlas (row 0 at the top, as PNG stores it) has its centre at
// u = (x + 0.5) / width, v = 1 - (y + 0.5) / height.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "algo/core/result.hpp"

namespace fb {

struct TexelMap {
  int width = 0;
  int height = 0;
  std::vector<std::int32_t> triangle;  // per texel: the triangle it shows, or -1
  std::vector<Eigen::Vector3f> bary;   // per texel: weights of the triangle's three corners
  int covered = 0;                     // texels whose centre lies in a triangle
  int rim = 0;  // texels up to 1.5 texels outside every triangle: the nearest one's nearest point

  std::size_t index(int x, int y) const {
    return static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + x;
  }
};

// `uvs`: (u, v) pairs; `triangle_uvs`: the UV index of each triangle corner (3 per triangle).
// Fails on an index out of range or a side outside [16, 8192].
Result<TexelMap> make_texel_map(std::span<const float> uvs,
                                std::span<const std::uint32_t> triangle_uvs, int width, int height);

// A point of the mesh (3 floats per vertex) at a texel, with the mesh's triangles.
inline Eigen::Vector3f texel_point(const TexelMap& map, std::size_t texel,
                                   std::span<const std::uint32_t> triangles,
                                   std::span<const float> vertices) {
  const auto t = static_cast<std::size_t>(map.triangle[texel]);
  const Eigen::Vector3f& b = map.bary[texel];
  Eigen::Vector3f p = Eigen::Vector3f::Zero();
  for (int k = 0; k < 3; ++k) {
    const std::size_t v = triangles[3 * t + k];
    p += b[k] * Eigen::Vector3f(vertices[3 * v], vertices[3 * v + 1], vertices[3 * v + 2]);
  }
  return p;
}

}  // namespace fb
