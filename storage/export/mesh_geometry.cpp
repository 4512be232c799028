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
