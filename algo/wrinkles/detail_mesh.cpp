#include "algo/wrinkles/detail_mesh.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <unordered_map>

#include "algo/texture/texel_map.hpp"

namespace fb {

namespace {

// The mesh being refined: positions and the UV layout side by side (OBJ indexes them per
// corner, so a seam edge has one position midpoint and one UV midpoint per side).
struct Work {
  std::vector<float> positions, uvs;
  std::vector<std::uint32_t> triangles, triangle_uvs;
  std::vector<char> refine;  // per triangle: split into four at the next level
  std::vector<std::array<std::uint32_t, 2>> parents;  // per vertex made: its edge's ends
};

std::uint64_t edge_key(std::uint32_t a, std::uint32_t b) {
  return a < b ? (std::uint64_t{a} << 32) | b : (std::uint64_t{b} << 32) | a;
}

// The midpoint of (a, b) in a list of `dim`-float items, made once per edge.
class Midpoints {
 public:
  Midpoints(std::vector<float>& items, int dim,
            std::vector<std::array<std::uint32_t, 2>>* parents = nullptr)
      : items_(items), dim_(dim), parents_(parents) {}
  std::uint32_t at(std::uint32_t a, std::uint32_t b) {
    const auto [it, added] = index_.try_emplace(edge_key(a, b), 0u);
    if (added) {
      it->second = static_cast<std::uint32_t>(items_.size() / dim_);
      if (parents_ != nullptr) parents_->push_back({a, b});
      for (int k = 0; k < dim_; ++k)
        items_.push_back(0.5f * (items_[dim_ * a + k] + items_[dim_ * b + k]));
    }
    return it->second;
  }
  bool has(std::uint32_t a, std::uint32_t b) const { return index_.count(edge_key(a, b)) > 0; }

 private:
  std::vector<float>& items_;
  int dim_;
  std::vector<std::array<std::uint32_t, 2>>* parents_;
  std::unordered_map<std::uint64_t, std::uint32_t> index_;
};

// One level: triangles marked `refine` (and any with all three edges split) into four; their
// unmarked neighbours into two or three, so no edge keeps a hanging midpoint.
void subdivide_once(Work& w) {
  Midpoints pos(w.positions, 3, &w.parents), uv(w.uvs, 2);
  const std::size_t count = w.triangles.size() / 3;
  for (std::size_t t = 0; t < count; ++t)
    if (w.refine[t])
      for (int k = 0; k < 3; ++k) pos.at(w.triangles[3 * t + k], w.triangles[3 * t + (k + 1) % 3]);
  Work out;
  auto emit = [&](std::array<std::uint32_t, 3> p, std::array<std::uint32_t, 3> q, bool refine) {
    out.triangles.insert(out.triangles.end(), p.begin(), p.end());
    out.triangle_uvs.insert(out.triangle_uvs.end(), q.begin(), q.end());
    out.refine.push_back(refine ? 1 : 0);
  };
  for (std::size_t t = 0; t < count; ++t) {
    std::array<std::uint32_t, 3> a{}, q{};
    for (int k = 0; k < 3; ++k) a[k] = w.triangles[3 * t + k], q[k] = w.triangle_uvs[3 * t + k];
    std::array<bool, 3> split{};
    int n = 0;
    for (int k = 0; k < 3; ++k) n += split[k] = pos.has(a[k], a[(k + 1) % 3]);
    if (n == 0) {
      emit(a, q, false);
      continue;
    }
    // Rotate so that the split edges come first: edge 0 = (a0, a1), edge 1 = (a1, a2).
    int r = 0;
    if (n == 1)
      r = split[0] ? 0 : split[1] ? 1 : 2;
    else if (n == 2)
      r = !split[2] ? 0 : !split[0] ? 1 : 2;
    std::rotate(a.begin(), a.begin() + r, a.end());
    std::rotate(q.begin(), q.begin() + r, q.end());
    const std::uint32_t m01 = pos.at(a[0], a[1]), u01 = uv.at(q[0], q[1]);
    if (n == 1) {
      emit({a[0], m01, a[2]}, {q[0], u01, q[2]}, false);
      emit({m01, a[1], a[2]}, {u01, q[1], q[2]}, false);
      continue;
    }
    const std::uint32_t m12 = pos.at(a[1], a[2]), u12 = uv.at(q[1], q[2]);
    if (n == 2 && !w.refine[t]) {
      emit({m01, a[1], m12}, {u01, q[1], u12}, false);
      emit({a[0], m01, m12}, {q[0], u01, u12}, false);
      emit({a[0], m12, a[2]}, {q[0], u12, q[2]}, false);
      continue;
    }
    const std::uint32_t m20 = pos.at(a[2], a[0]), u20 = uv.at(q[2], q[0]);
    emit({a[0], m01, m20}, {q[0], u01, u20}, true);
    emit({m01, a[1], m12}, {u01, q[1], u12}, true);
    emit({m20, m12, a[2]}, {u20, u12, q[2]}, true);
    emit({m01, m12, m20}, {u01, u12, u20}, true);
  }
  out.positions = std::move(w.positions);
  out.uvs = std::move(w.uvs);
  out.parents = std::move(w.parents);
  w = std::move(out);
}

}  // namespace

std::vector<float> interpolate_midpoints(std::span<const float> values, int dim,
                                         std::span<const std::array<std::uint32_t, 2>> parents) {
  std::vector<float> out(values.begin(), values.end());
  const std::size_t d = static_cast<std::size_t>(dim);
  out.reserve(out.size() + d * parents.size());
  for (const auto& [a, b] : parents)
    for (std::size_t k = 0; k < d; ++k) out.push_back(0.5f * (out[d * a + k] + out[d * b + k]));
  return out;
}

std::vector<float> corner_mean_heights(const FloatImage& map,
                                       const std::vector<std::int32_t>& covered_triangle,
                                       std::size_t vertex_count,
                                       std::span<const std::uint32_t> triangles,
                                       std::span<const float> uvs,
                                       std::span<const std::uint32_t> triangle_uvs) {
  std::vector<float> sum(vertex_count, 0.0f);
  std::vector<int> corners(vertex_count, 0);
  for (std::size_t c = 0; c < triangles.size(); ++c) {
    const std::uint32_t v = triangles[c], q = triangle_uvs[c];
    sum[v] += sample_displacement(map, covered_triangle, uvs[2 * q], uvs[2 * q + 1]);
    ++corners[v];
  }
  for (std::size_t v = 0; v < vertex_count; ++v)
    sum[v] = corners[v] > 0 ? sum[v] / static_cast<float>(corners[v]) : 0.0f;
  return sum;
}

float sample_displacement(const FloatImage& map, const std::vector<std::int32_t>& covered_triangle,
                          float u, float v) {
  const float fx = u * static_cast<float>(map.width) - 0.5f;
  const float fy = (1.0f - v) * static_cast<float>(map.height) - 0.5f;
  const int x0 = static_cast<int>(std::floor(fx)), y0 = static_cast<int>(std::floor(fy));
  const float ax = fx - static_cast<float>(x0), ay = fy - static_cast<float>(y0);
  float sum = 0.0f, weight = 0.0f;
  for (int dy = 0; dy < 2; ++dy)
    for (int dx = 0; dx < 2; ++dx) {
      const int x = x0 + dx, y = y0 + dy;
      if (x < 0 || y < 0 || x >= map.width || y >= map.height) continue;
      const std::size_t i = static_cast<std::size_t>(y) * map.width + x;
      if (covered_triangle[i] < 0) continue;
      const float k = (dx ? ax : 1.0f - ax) * (dy ? ay : 1.0f - ay);
      sum += k * map.pixels[i];
      weight += k;
    }
  return weight > 1e-6f ? sum / weight : 0.0f;
}

Result<DetailMesh> subdivided_detail_mesh(const DetailMeshInput& in,
                                          const DetailMeshOptions& options) {
  if (in.displacement_mm == nullptr || in.displacement_mm->width <= 0)
    return fail("detail mesh: no displacement map");
  if (in.triangle_uvs.size() != in.triangles.size())
    return fail("detail mesh: the UV layout has " + std::to_string(in.triangle_uvs.size() / 3) +
                " triangles, the mesh " + std::to_string(in.triangles.size() / 3));
  const FloatImage& disp = *in.displacement_mm;
  auto map = make_texel_map(in.uvs, in.triangle_uvs, disp.width, disp.height);
  if (!map) return map.failure();
  const std::size_t count = in.triangles.size() / 3;
  Work w;
  w.positions.assign(in.vertices.begin(), in.vertices.end());
  w.uvs.assign(in.uvs.begin(), in.uvs.end());
  w.triangles.assign(in.triangles.begin(), in.triangles.end());
  w.triangle_uvs.assign(in.triangle_uvs.begin(), in.triangle_uvs.end());
  w.refine.assign(count, 0);
  for (std::size_t i = 0; i < map->triangle.size(); ++i)
    if (map->triangle[i] >= 0 && std::abs(disp.pixels[i]) > options.min_height_mm)
      w.refine[static_cast<std::size_t>(map->triangle[i])] = 1;
  // The margin: triangles sharing a vertex with marked ones, ring by ring.
  const std::size_t vertex_count = in.vertices.size() / 3;
  for (int ring = 0; ring < options.margin_rings; ++ring) {
    std::vector<char> touched(vertex_count, 0);
    for (std::size_t t = 0; t < count; ++t)
      if (w.refine[t])
        for (int k = 0; k < 3; ++k) touched[in.triangles[3 * t + k]] = 1;
    for (std::size_t t = 0; t < count; ++t)
      for (int k = 0; k < 3; ++k) w.refine[t] |= touched[in.triangles[3 * t + k]];
  }
  DetailMesh out;
  out.refined_triangles = static_cast<int>(std::count(w.refine.begin(), w.refine.end(), 1));
  for (int level = 0; level < options.levels; ++level) subdivide_once(w);

  // Heights per vertex: the mean over its corners' UVs (a seam vertex has one per side; the
  // map holds the same surface point's height on both).
  out.heights = corner_mean_heights(disp, map->triangle, w.positions.size() / 3, w.triangles, w.uvs,
                                    w.triangle_uvs);
  out.positions = displace_mesh(w.positions, w.triangles, out.heights, options.smoothing);
  out.undisplaced = std::move(w.positions);
  out.triangles = std::move(w.triangles);
  out.uvs = std::move(w.uvs);
  out.triangle_uvs = std::move(w.triangle_uvs);
  out.parents = std::move(w.parents);
  return out;
}

}  // namespace fb
