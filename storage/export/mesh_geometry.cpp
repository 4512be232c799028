#include "storage/export/mesh_geometry.hpp"

#include <cmath>
#include <unordered_map>

namespace fb {

bool MeshUvs::fits(std::span<const std::uint32_t> triangles) const {
  if (uvs.empty() || uvs.size() % 2 != 0 || triangle_uvs.size() != triangles.size()) return false;
  const std::size_t count = uvs.size() / 2;
  for (auto uv : triangle_uvs) {
    if (uv >= count) return false;
  }
  return true;
}

std::vector<float> vertex_normals(std::span<const float> positions,
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

SplitMesh split_seams(std::span<const std::uint32_t> triangles, const MeshUvs& uvs) {
  SplitMesh out;
  out.triangles.reserve(triangles.size());
  std::unordered_map<std::uint64_t, std::uint32_t> index;
  index.reserve(triangles.size() / 2);
  for (std::size_t c = 0; c < triangles.size(); ++c) {
    const std::uint32_t v = triangles[c];
    const std::uint32_t uv = uvs.triangle_uvs[c];
    const std::uint64_t key = (std::uint64_t{v} << 32) | uv;
    const auto [it, added] =
        index.emplace(key, static_cast<std::uint32_t>(out.source_vertex.size()));
    if (added) {
      out.source_vertex.push_back(v);
      out.uv_index.push_back(uv);
    }
    out.triangles.push_back(it->second);
  }
  return out;
}

}  // namespace fb
