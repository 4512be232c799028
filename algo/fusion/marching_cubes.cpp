#include "algo/fusion/marching_cubes.hpp"

#include <unordered_map>

#include "algo/fusion/marching_cubes_tables.hpp"

namespace fb {
namespace {

float tsdf_at(const TsdfVolume& v, int x, int y, int z) {
  return static_cast<float>(v.at(x, y, z).tsdf()) * (1.0f / TsdfVolume::kTsdfScale);
}

Eigen::Vector3f gradient(const TsdfVolume& v, int x, int y, int z) {
  const int n = v.resolution();
  auto f = [&](int a, int b, int c) {
    a = std::clamp(a, 0, n - 1);
    b = std::clamp(b, 0, n - 1);
    c = std::clamp(c, 0, n - 1);
    return tsdf_at(v, a, b, c);
  };
  return {f(x + 1, y, z) - f(x - 1, y, z), f(x, y + 1, z) - f(x, y - 1, z),
          f(x, y, z + 1) - f(x, y, z - 1)};
}

}  // namespace

TriangleMesh extract_mesh(const TsdfVolume& volume, const MeshOptions& options) {
  TriangleMesh mesh;
  const int n = volume.resolution();
  const int nb = volume.bricks_per_side();
  const float vs = volume.voxel_size();
  const Eigen::Vector3f origin = volume.origin() + Eigen::Vector3f::Constant(0.5f * vs);
  // Edge key: (voxel index of the edge's first corner) * 3 + axis.
  std::unordered_map<std::uint64_t, int> edge_vertex;
  const auto& touched = volume.touched();
  for (int b = 0; b < static_cast<int>(touched.size()); ++b) {
    if (!touched[b]) continue;
    const int bx = (b % nb) * 8, by = ((b / nb) % nb) * 8, bz = (b / (nb * nb)) * 8;
    for (int z = bz; z < bz + 8; ++z) {
      for (int y = by; y < by + 8; ++y) {
        for (int x = bx; x < bx + 8; ++x) {
          if (x + 1 >= n || y + 1 >= n || z + 1 >= n) continue;
          float f[8];
          int cube = 0;
          bool seen = true;
          for (int c = 0; c < 8; ++c) {
            const Voxel& v =
                volume.at(x + mc::kCorner[c][0], y + mc::kCorner[c][1], z + mc::kCorner[c][2]);
            if (v.weight() < options.min_weight) {
              seen = false;
              break;
            }
            f[c] = static_cast<float>(v.tsdf()) * (1.0f / TsdfVolume::kTsdfScale);
            if (f[c] < 0.0f) cube |= 1 << c;
          }
          if (!seen || cube == 0 || cube == 255) continue;
          const int edges = mc::kEdgeTable[cube];
          int ids[12];
          for (int e = 0; e < 12; ++e) {
            if (!(edges & (1 << e))) continue;
            const int c0 = mc::kEdgeCorners[e][0], c1 = mc::kEdgeCorners[e][1];
            const int x0 = x + mc::kCorner[c0][0], y0 = y + mc::kCorner[c0][1],
                      z0 = z + mc::kCorner[c0][2];
            const int axis = mc::kCorner[c1][0] != mc::kCorner[c0][0]   ? 0
                             : mc::kCorner[c1][1] != mc::kCorner[c0][1] ? 1
                                                                        : 2;
            const std::uint64_t key =
                ((static_cast<std::uint64_t>(z0) * n + y0) * n + x0) * 3 + axis;
            auto it = edge_vertex.find(key);
            if (it != edge_vertex.end()) {
              ids[e] = it->second;
              continue;
            }
            // Linear interpolation of the zero crossing along the edge.
            const float a = f[c0] / (f[c0] - f[c1]);
            Eigen::Vector3f g(static_cast<float>(x0), static_cast<float>(y0),
                              static_cast<float>(z0));
            g[axis] += a;
            const int x1 = x + mc::kCorner[c1][0], y1 = y + mc::kCorner[c1][1],
                      z1 = z + mc::kCorner[c1][2];
            Eigen::Vector3f nrm =
                (1.0f - a) * gradient(volume, x0, y0, z0) + a * gradient(volume, x1, y1, z1);
            const float len = nrm.norm();
            nrm = len > 0.0f ? Eigen::Vector3f(nrm / len) : Eigen::Vector3f::UnitZ();
            ids[e] = static_cast<int>(mesh.vertices.size());
            mesh.vertices.push_back(origin + g * vs);
            mesh.normals.push_back(nrm);
            edge_vertex.emplace(key, ids[e]);
          }
          // The table winds triangles clockwise seen from outside (sdf > 0); emit them
          // counter-clockwise so winding and normals agree.
          for (int t = 0; mc::kTriTable[cube][t] >= 0; t += 3) {
            mesh.triangles.emplace_back(ids[mc::kTriTable[cube][t]],
                                        ids[mc::kTriTable[cube][t + 2]],
                                        ids[mc::kTriTable[cube][t + 1]]);
          }
        }
      }
    }
  }
  return mesh;
}

}  // namespace fb
