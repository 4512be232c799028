#include "algo/wrinkles/wrinkle_geometry.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>

#include "algo/core/mesh_normals.hpp"
#include "algo/render/rasterizer.hpp"

namespace fb {

namespace {

Eigen::Vector3f vertex_at(std::span<const float> v, std::size_t i) {
  return {v[3 * i], v[3 * i + 1], v[3 * i + 2]};
}

// The view's front-most surface per pixel, to tell seen points from hidden ones.
class HeightLookup {
 public:
  HeightLookup(std::span<const float> vertices, std::span<const std::uint32_t> triangles,
               const HeightView& view)
      : view_(view) {
    std::vector<Eigen::Vector3f> posed(vertices.size() / 3);
    for (std::size_t v = 0; v < posed.size(); ++v)
      posed[v] = view.camera_from_model.apply(vertex_at(vertices, v).cast<double>()).cast<float>();
    raster_.reset(view.intrinsics.width, view.intrinsics.height);
    ok_ = static_cast<bool>(rasterize(view.intrinsics, posed, triangles, {}, raster_));
  }

  // The height at a model-frame point (0 when hidden, outside the image or the domain).
  float at(const Eigen::Vector3f& model_point) const {
    if (!ok_ || !view_.height_mm || !view_.domain) return 0.0f;
    const Eigen::Vector3d p = view_.camera_from_model.apply(model_point.cast<double>());
    if (p.z() <= 0.0) return 0.0f;
    const Eigen::Vector2d px = view_.intrinsics.project(p);
    const int x = static_cast<int>(std::lround(px.x())), y = static_cast<int>(std::lround(px.y()));
    const FloatImage& h = *view_.height_mm;
    if (x < 0 || y < 0 || x >= h.width || y >= h.height || !view_.domain->at(x, y)) return 0.0f;
    if (p.z() > raster_.depth[raster_.index(x, y)] + view_.visibility_tolerance_mm) return 0.0f;
    // Bilinear between the four pixels around the point (edges clamped).
    const double fx = std::clamp(px.x(), 0.0, h.width - 1.0),
                 fy = std::clamp(px.y(), 0.0, h.height - 1.0);
    const int x0 = std::min(static_cast<int>(fx), h.width - 2),
              y0 = std::min(static_cast<int>(fy), h.height - 2);
    const auto ax = static_cast<float>(fx - x0), ay = static_cast<float>(fy - y0);
    return (1 - ay) * ((1 - ax) * h.at(x0, y0) + ax * h.at(x0 + 1, y0)) +
           ay * ((1 - ax) * h.at(x0, y0 + 1) + ax * h.at(x0 + 1, y0 + 1));
  }

 private:
  const HeightView& view_;
  RasterBuffers raster_;
  bool ok_ = false;
};

std::vector<std::vector<std::uint32_t>> neighbours(std::size_t n,
                                                   std::span<const std::uint32_t> triangles) {
  std::vector<std::vector<std::uint32_t>> out(n);
  for (std::size_t t = 0; t + 2 < triangles.size(); t += 3)
    for (int k = 0; k < 3; ++k) {
      const auto a = triangles[t + k], b = triangles[t + (k + 1) % 3];
      out[a].push_back(b);
      out[b].push_back(a);
    }
  for (auto& l : out) {
    std::sort(l.begin(), l.end());
    l.erase(std::unique(l.begin(), l.end()), l.end());
  }
  return out;
}

}  // namespace

std::vector<float> vertex_heights(std::span<const float> vertices,
                                  std::span<const std::uint32_t> triangles,
                                  const HeightView& view) {
  const HeightLookup lookup(vertices, triangles, view);
  std::vector<float> out(vertices.size() / 3);
  for (std::size_t v = 0; v < out.size(); ++v) out[v] = lookup.at(vertex_at(vertices, v));
  return out;
}

std::vector<float> displace_mesh(std::span<const float> vertices,
                                 std::span<const std::uint32_t> triangles,
                                 std::span<const float> heights, const DisplaceOptions& options) {
  const std::size_t n = vertices.size() / 3;
  const auto adj = neighbours(n, triangles);
  // Rings around the border between displaced and undisplaced vertices.
  std::vector<int> ring(n, -1);
  std::vector<std::uint32_t> front;
  for (std::size_t v = 0; v < n; ++v)
    for (const auto u : adj[v])
      if ((heights[v] != 0.0f) != (heights[u] != 0.0f)) {
        ring[v] = 0;
        front.push_back(static_cast<std::uint32_t>(v));
        break;
      }
  for (int r = 1; r <= options.border_rings; ++r) {
    std::vector<std::uint32_t> next;
    for (const auto v : front)
      for (const auto u : adj[v])
        if (ring[u] < 0) ring[u] = r, next.push_back(u);
    front.swap(next);
  }
  std::vector<float> h(heights.begin(), heights.end()), tmp = h;
  for (int it = 0; it < options.smoothing_iterations; ++it) {
    for (std::size_t v = 0; v < n; ++v) {
      if (ring[v] < 0 || adj[v].empty()) continue;
      float mean = 0.0f;
      for (const auto u : adj[v]) mean += h[u];
      tmp[v] = 0.5f * h[v] + 0.5f * mean / static_cast<float>(adj[v].size());
    }
    h = tmp;
  }
  const std::vector<float> normals = vertex_normals(vertices, triangles);
  std::vector<float> out(vertices.begin(), vertices.end());
  for (std::size_t i = 0; i < out.size(); ++i) out[i] += h[i / 3] * normals[i];
  return out;
}

Result<DetailMaps> detail_maps(const TexelMap& map, std::span<const float> uvs,
                               std::span<const std::uint32_t> triangle_uvs,
                               std::span<const float> vertices,
                               std::span<const std::uint32_t> triangles, const HeightView& view) {
  if (triangle_uvs.size() != triangles.size())
    return fail("detail maps: the UV layout has " + std::to_string(triangle_uvs.size() / 3) +
                " triangles, the mesh " + std::to_string(triangles.size() / 3));
  const HeightLookup lookup(vertices, triangles, view);
  DetailMaps out;
  out.displacement_mm.resize(map.width, map.height);
  for (std::size_t i = 0; i < map.triangle.size(); ++i) {
    const float h =
        map.triangle[i] < 0 ? 0.0f : lookup.at(texel_point(map, i, triangles, vertices));
    out.displacement_mm.pixels[i] = h;
    out.texels_with_detail += h != 0.0f;
  }
  out.normal_map.resize(map.width, map.height);
  const Rgb8 flat{128, 128, 255};
  std::fill(out.normal_map.pixels.begin(), out.normal_map.pixels.end(), flat);
  const FloatImage& d = out.displacement_mm;
  auto at = [&](int x, int y, float fallback) {
    if (x < 0 || y < 0 || x >= map.width || y >= map.height || map.triangle[map.index(x, y)] < 0)
      return fallback;
    return d.at(x, y);
  };
  for (int y = 0; y < map.height; ++y)
    for (int x = 0; x < map.width; ++x) {
      const std::int32_t t = map.triangle[map.index(x, y)];
      const float c = d.at(x, y);
      if (t < 0) continue;
      // Height change per UV unit (texel row 0 is v = 1: v grows upwards).
      const double dh_du = 0.5 * (at(x + 1, y, c) - at(x - 1, y, c)) * map.width;
      const double dh_dv = 0.5 * (at(x, y - 1, c) - at(x, y + 1, c)) * map.height;
      if (dh_du == 0.0 && dh_dv == 0.0) continue;
      // The triangle's surface per UV unit: P = P0 + J (uv - uv0).
      Eigen::Vector3d p[3];
      Eigen::Vector2d q[3];
      for (int k = 0; k < 3; ++k) {
        p[k] = vertex_at(vertices, triangles[3 * t + k]).cast<double>();
        const std::uint32_t uv = triangle_uvs[3 * t + k];
        q[k] = {uvs[2 * uv], uvs[2 * uv + 1]};
      }
      Eigen::Matrix<double, 3, 2> e;
      e << p[1] - p[0], p[2] - p[0];
      Eigen::Matrix2d f;
      f << q[1] - q[0], q[2] - q[0];
      if (std::abs(f.determinant()) < 1e-12) continue;
      const Eigen::Matrix<double, 3, 2> j = e * f.inverse();
      const Eigen::Vector3d normal = j.col(0).cross(j.col(1)).normalized();
      // The height's gradient on the surface tilts the normal against it.
      const Eigen::Vector3d grad =
          j * (j.transpose() * j).inverse() * Eigen::Vector2d(dh_du, dh_dv);
      const Eigen::Vector3d n = (normal - grad).normalized();
      const Eigen::Vector3d tu = j.col(0).normalized();
      const Eigen::Vector3d tv = normal.cross(tu);
      const Eigen::Vector3d local(n.dot(tu), n.dot(tv), n.dot(normal));
      auto byte = [](double v) {
        return static_cast<std::uint8_t>(std::clamp(std::lround(127.5 * (v + 1.0)), 0L, 255L));
      };
      out.normal_map.at(x, y) = {byte(local.x()), byte(local.y()), byte(local.z())};
    }
  return out;
}

}  // namespace fb
