#include "sim/subject/remesh.hpp"

#include <algorithm>
#include <unordered_map>

#include <Eigen/Geometry>

namespace fb {

Points Remesh::apply(const Points& original) const {
  Points out(vertex_count(), 3);
  for (std::size_t i = 0; i < sources.size(); ++i) {
    Eigen::RowVector3d p = Eigen::RowVector3d::Zero();
    for (int k = 0; k < 3; ++k)
      if (weights[i][k] != 0) p += weights[i][k] * original.row(sources[i][k]);
    out.row(static_cast<Eigen::Index>(i)) = p;
  }
  return out;
}

namespace {

Remesh identity_vertices(int vertex_count) {
  Remesh r;
  for (int v = 0; v < vertex_count; ++v) {
    const auto u = static_cast<std::uint32_t>(v);
    r.sources.push_back({u, u, u});
    r.weights.push_back({1.0, 0.0, 0.0});
  }
  return r;
}

}  // namespace

Remesh split_at_centroids(std::span<const std::uint32_t> triangles, int vertex_count,
                          int region_end, int max_vertices) {
  Remesh r = identity_vertices(vertex_count);
  const auto end = static_cast<std::uint32_t>(region_end);
  for (std::size_t t = 0; t + 2 < triangles.size(); t += 3) {
    const std::uint32_t a = triangles[t], b = triangles[t + 1], c = triangles[t + 2];
    if (r.vertex_count() >= max_vertices || a >= end || b >= end || c >= end) {
      r.triangles.insert(r.triangles.end(), {a, b, c});
      continue;
    }
    const auto m = static_cast<std::uint32_t>(r.vertex_count());
    r.sources.push_back({a, b, c});
    r.weights.push_back({1.0 / 3, 1.0 / 3, 1.0 / 3});
    r.triangles.insert(r.triangles.end(), {a, b, m, b, c, m, c, a, m});
  }
  return r;
}

Remesh flip_quad_diagonals(std::span<const std::uint32_t> triangles, int vertex_count) {
  Remesh r = identity_vertices(vertex_count);
  std::size_t t = 0;
  for (; t + 5 < triangles.size(); t += 6) {
    const std::uint32_t* p = &triangles[t];
    // Find the shared edge (a, b) of (p0 p1 p2) and (p3 p4 p5); the quad is a c b d.
    int ia = -1, ib = -1;
    for (int i = 0; i < 3 && ia < 0; ++i)
      for (int j = 0; j < 3; ++j)
        if (p[i] == p[3 + (j + 1) % 3] && p[(i + 1) % 3] == p[3 + j]) ia = i, ib = j;
    if (ia < 0) {
      r.triangles.insert(r.triangles.end(), p, p + 6);
      continue;
    }
    const std::uint32_t a = p[ia], b = p[(ia + 1) % 3], c = p[(ia + 2) % 3];
    const std::uint32_t d = p[3 + (ib + 2) % 3];
    r.triangles.insert(r.triangles.end(), {c, a, d, d, b, c});
  }
  r.triangles.insert(r.triangles.end(), triangles.begin() + static_cast<std::ptrdiff_t>(t),
                     triangles.end());
  return r;
}

namespace {

using Tri = std::array<std::uint32_t, 3>;

std::vector<bool> boundary_vertices(const std::vector<Tri>& tris, const std::vector<bool>& dead,
                                    int n) {
  std::unordered_map<std::uint64_t, int> count;
  for (std::size_t t = 0; t < tris.size(); ++t) {
    if (dead[t]) continue;
    for (int k = 0; k < 3; ++k) {
      const auto e = std::minmax(tris[t][k], tris[t][(k + 1) % 3]);
      ++count[(std::uint64_t{e.first} << 32) | e.second];
    }
  }
  std::vector<bool> out(static_cast<std::size_t>(n), false);
  for (const auto& [key, c] : count)
    if (c == 1) out[key >> 32] = out[key & 0xffffffffu] = true;
  return out;
}

std::vector<std::uint32_t> ring_of(std::uint32_t u, const std::vector<int>& around,
                                   const std::vector<Tri>& tris) {
  std::vector<std::uint32_t> ring;
  for (int t : around)
    for (std::uint32_t w : tris[static_cast<std::size_t>(t)])
      if (w != u) ring.push_back(w);
  std::sort(ring.begin(), ring.end());
  ring.erase(std::unique(ring.begin(), ring.end()), ring.end());
  return ring;
}

Eigen::RowVector3d normal(const Points& p, const Tri& t) {
  return (p.row(t[1]) - p.row(t[0])).cross(p.row(t[2]) - p.row(t[0]));
}

// Whether u -> v keeps a manifold (two common neighbours) and turns no triangle over.
bool can_collapse(std::uint32_t u, std::uint32_t v, const std::vector<std::vector<int>>& vt,
                  const std::vector<Tri>& tris, const Points& p) {
  const auto ru = ring_of(u, vt[u], tris), rv = ring_of(v, vt[v], tris);
  std::vector<std::uint32_t> common;
  std::set_intersection(ru.begin(), ru.end(), rv.begin(), rv.end(), std::back_inserter(common));
  if (common.size() != 2) return false;
  for (int t : vt[u]) {
    Tri tri = tris[static_cast<std::size_t>(t)];
    if (std::find(tri.begin(), tri.end(), v) != tri.end()) continue;
    const Eigen::RowVector3d before = normal(p, tri);
    std::replace(tri.begin(), tri.end(), u, v);
    const Eigen::RowVector3d after = normal(p, tri);
    if (before.dot(after) < 0.5 * before.norm() * after.norm()) return false;
  }
  return true;
}

// One pass of independent collapses; returns how many.
int collapse_pass(std::vector<Tri>& tris, std::vector<bool>& dead, std::vector<bool>& alive,
                  const std::vector<bool>& pinned, const Points& p, int& alive_count, int target) {
  const int n = static_cast<int>(alive.size());
  std::vector<std::vector<int>> vt(static_cast<std::size_t>(n));
  for (std::size_t t = 0; t < tris.size(); ++t)
    if (!dead[t])
      for (std::uint32_t w : tris[t]) vt[w].push_back(static_cast<int>(t));
  const std::vector<bool> boundary = boundary_vertices(tris, dead, n);
  std::vector<bool> touched(static_cast<std::size_t>(n), false);
  int collapsed = 0;
  for (std::uint32_t u = 0; u < static_cast<std::uint32_t>(n) && alive_count > target; ++u) {
    if (!alive[u] || pinned[u] || boundary[u] || touched[u] || vt[u].empty()) continue;
    auto ring = ring_of(u, vt[u], tris);
    std::sort(ring.begin(), ring.end(), [&](std::uint32_t a, std::uint32_t b) {
      return (p.row(a) - p.row(u)).squaredNorm() < (p.row(b) - p.row(u)).squaredNorm();
    });
    for (std::uint32_t v : ring) {
      if (touched[v] || !can_collapse(u, v, vt, tris, p)) continue;
      for (int t : vt[u]) {
        Tri& tri = tris[static_cast<std::size_t>(t)];
        if (std::find(tri.begin(), tri.end(), v) != tri.end())
          dead[static_cast<std::size_t>(t)] = true;
        else
          std::replace(tri.begin(), tri.end(), u, v);
      }
      alive[u] = false;
      --alive_count;
      touched[u] = touched[v] = true;
      for (std::uint32_t w : ring) touched[w] = true;
      ++collapsed;
      break;
    }
  }
  return collapsed;
}

}  // namespace

Remesh decimate(std::span<const std::uint32_t> triangles, const Points& positions, double fraction,
                std::span<const std::uint32_t> keep) {
  const int n = static_cast<int>(positions.rows());
  std::vector<Tri> tris;
  for (std::size_t t = 0; t + 2 < triangles.size(); t += 3)
    tris.push_back({triangles[t], triangles[t + 1], triangles[t + 2]});
  std::vector<bool> dead(tris.size(), false), alive(static_cast<std::size_t>(n), true);
  std::vector<bool> pinned(static_cast<std::size_t>(n), false);
  for (std::uint32_t k : keep) pinned[k] = true;
  int alive_count = n;
  const int target = static_cast<int>(fraction * n);
  for (int pass = 0; pass < 30 && alive_count > target; ++pass)
    if (collapse_pass(tris, dead, alive, pinned, positions, alive_count, target) == 0) break;
  Remesh r;
  std::vector<std::uint32_t> index(static_cast<std::size_t>(n), 0);
  for (int v = 0; v < n; ++v) {
    if (!alive[static_cast<std::size_t>(v)]) continue;
    index[static_cast<std::size_t>(v)] = static_cast<std::uint32_t>(r.sources.size());
    const auto u = static_cast<std::uint32_t>(v);
    r.sources.push_back({u, u, u});
    r.weights.push_back({1.0, 0.0, 0.0});
  }
  for (std::size_t t = 0; t < tris.size(); ++t)
    if (!dead[t])
      for (std::uint32_t w : tris[t]) r.triangles.push_back(index[w]);
  return r;
}

}  // namespace fb
