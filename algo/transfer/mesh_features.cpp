#include "algo/transfer/mesh_features.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "algo/core/mesh_normals.hpp"

namespace fb {

namespace {

constexpr double kDistance = 1500;  // mm from the front: nearly orthographic

// Camera frame (x right, y down, z forward) of a model point seen from +z about `centre`.
Eigen::Vector3f to_camera(const Eigen::RowVector3d& p, const Eigen::RowVector3d& centre) {
  const Eigen::RowVector3d d = p - centre;
  return Eigen::Vector3f(static_cast<float>(d.x()), static_cast<float>(-d.y()),
                         static_cast<float>(kDistance - d.z()));
}

}  // namespace

FrontalRender render_frontal(const Points& points, std::span<const std::uint32_t> triangles,
                             int side, double depth_mm) {
  const double zmax = points.col(2).maxCoeff();
  Eigen::RowVector3d lo = Eigen::RowVector3d::Constant(1e300), hi = -lo;
  for (Eigen::Index v = 0; v < points.rows(); ++v) {
    if (points(v, 2) < zmax - depth_mm) continue;
    lo = lo.cwiseMin(points.row(v)), hi = hi.cwiseMax(points.row(v));
  }
  const Eigen::RowVector3d centre(0.5 * (lo.x() + hi.x()), 0.5 * (lo.y() + hi.y()), zmax);
  const double half = 0.6 * std::max(hi.x() - lo.x(), hi.y() - lo.y());
  FrontalRender r;
  r.camera.width = r.camera.height = side;
  r.camera.fx = r.camera.fy = kDistance * side / (2.0 * std::max(half, 1e-6));
  r.camera.cx = r.camera.cy = (side - 1) / 2.0;
  std::vector<Eigen::Vector3f> posed(static_cast<std::size_t>(points.rows()));
  for (Eigen::Index v = 0; v < points.rows(); ++v)
    posed[static_cast<std::size_t>(v)] = to_camera(points.row(v), centre);
  const std::vector<float> xyz = floats_from_points(points);
  const std::vector<float> normals = vertex_normals(xyz, triangles);
  r.raster.reset(side, side);
  r.image.resize(side, side);
  std::fill(r.image.pixels.begin(), r.image.pixels.end(), Rgb8{40, 40, 40});
  if (!rasterize(r.camera, posed, triangles, {}, r.raster)) return r;
  const Eigen::Vector3f light = Eigen::Vector3f(0.0f, 0.35f, 1.0f).normalized();
  for (int y = 0; y < side; ++y) {
    for (int x = 0; x < side; ++x) {
      const std::size_t i = r.raster.index(x, y);
      const std::int32_t t = r.raster.triangle[i];
      if (t == kNoTriangle) continue;
      const float b[3] = {1.0f - r.raster.bary1[i] - r.raster.bary2[i], r.raster.bary1[i],
                          r.raster.bary2[i]};
      Eigen::Vector3f n = Eigen::Vector3f::Zero();
      for (int c = 0; c < 3; ++c)
        n += b[c] *
             Eigen::Vector3f(normals.data() + 3 * std::size_t{triangles[3 * std::size_t(t) + c]});
      const float shade = 0.15f + 0.85f * std::max(0.0f, n.normalized().dot(light));
      const auto g = static_cast<std::uint8_t>(std::clamp(235.0f * shade, 0.0f, 255.0f));
      r.image.at(x, y) =
          Rgb8{g, static_cast<std::uint8_t>(g * 0.85f), static_cast<std::uint8_t>(g * 0.75f)};
    }
  }
  return r;
}

Result<Points> back_project(const FrontalRender& render, const Points& points,
                            std::span<const std::uint32_t> triangles,
                            std::span<const Eigen::Vector2d> pixels, int search_px) {
  const RasterBuffers& rb = render.raster;
  Points out(static_cast<Eigen::Index>(pixels.size()), 3);
  for (std::size_t k = 0; k < pixels.size(); ++k) {
    const int px = static_cast<int>(std::lround(pixels[k].x()));
    const int py = static_cast<int>(std::lround(pixels[k].y()));
    int best_d2 = search_px * search_px + 1;
    std::size_t best = 0;
    for (int dy = -search_px; dy <= search_px; ++dy)
      for (int dx = -search_px; dx <= search_px; ++dx) {
        const int x = px + dx, y = py + dy, d2 = dx * dx + dy * dy;
        if (x < 0 || y < 0 || x >= rb.width || y >= rb.height || d2 >= best_d2) continue;
        if (!rb.covered(x, y)) continue;
        best_d2 = d2, best = rb.index(x, y);
      }
    if (best_d2 > search_px * search_px)
      return fail("feature point " + std::to_string(k) + " at pixel (" + std::to_string(px) + ", " +
                  std::to_string(py) + ") is off the rendered mesh");
    const auto t = static_cast<std::size_t>(rb.triangle[best]);
    const double b1 = rb.bary1[best], b2 = rb.bary2[best];
    out.row(static_cast<Eigen::Index>(k)) = (1 - b1 - b2) * points.row(triangles[3 * t]) +
                                            b1 * points.row(triangles[3 * t + 1]) +
                                            b2 * points.row(triangles[3 * t + 2]);
  }
  return out;
}

}  // namespace fb
