// Area-weighted vertex normals of a triangle mesh: the one implementation the exporters (glTF,
// OBJ) and the texture builder share. Header-only, as algo/core is.
#pragma once

#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

namespace fb {

// Unit length; (0, 0, 1) for a vertex no triangle with area uses; 3 floats per vertex. Winding
// is counter-clockwise seen from outside.
inline std::vector<float> vertex_normals(std::span<const float> positions,
                                         std::span<const std::uint32_t> triangles) {
  const std::size_t nv = positions.size() / 3;
  std::vector<double> sum(3 * nv, 0.0);
  for (std::size_t t = 0; t + 2 < triangles.size(); t += 3) {
    const std::size_t a = triangles[t], b = triangles[t + 1], c = triangles[t + 2];
    if (a >= nv || b >= nv || c >= nv) continue;
    double u[3], w[3];
    for (int k = 0; k < 3; ++k) {
      u[k] = double{positions[3 * b + k]} - positions[3 * a + k];
      w[k] = double{positions[3 * c + k]} - positions[3 * a + k];
    }
    // The cross product's length is twice the area: summing it weights by area.
    const double n[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2],
                         u[0] * w[1] - u[1] * w[0]};
    for (std::size_t v : {a, b, c}) {
      for (int k = 0; k < 3; ++k) sum[3 * v + k] += n[k];
    }
  }
  std::vector<float> normals(3 * nv);
  for (std::size_t v = 0; v < nv; ++v) {
    const double x = sum[3 * v], y = sum[3 * v + 1], z = sum[3 * v + 2];
    const double length = std::sqrt(x * x + y * y + z * z);
    if (length > 0.0) {
      normals[3 * v] = static_cast<float>(x / length);
      normals[3 * v + 1] = static_cast<float>(y / length);
      normals[3 * v + 2] = static_cast<float>(z / length);
    } else {
      normals[3 * v + 2] = 1.0f;
    }
  }
  return normals;
}

}  // namespace fb
