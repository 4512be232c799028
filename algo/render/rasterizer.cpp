#include "algo/render/rasterizer.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace fb {

void RasterBuffers::reset(int w, int h) {
  width = w;
  height = h;
  const auto n = static_cast<std::size_t>(w) * static_cast<std::size_t>(h);
  depth.assign(n, std::numeric_limits<float>::infinity());
  triangle.assign(n, kNoTriangle);
  bary1.assign(n, 0.0f);
  bary2.assign(n, 0.0f);
}

Result<void> rasterize(const PinholeIntrinsics& k, std::span<const Eigen::Vector3f> vertices,
                       std::span<const std::uint32_t> triangles, const RasterOptions& options,
                       RasterBuffers& target) {
  const auto vertex_count = vertices.size();
  for (const auto index : triangles) {
    if (index >= vertex_count) {
      return fail("rasterize: triangle index " + std::to_string(index) + " is out of range (" +
                  std::to_string(vertex_count) + " vertices)");
    }
  }
  if (target.width <= 0 || target.height <= 0 ||
      target.depth.size() != static_cast<std::size_t>(target.width) * target.height) {
    return fail("rasterize: target buffers are not sized; call RasterBuffers::reset first");
  }
  const int w = target.width;
  const int h = target.height;
  const std::size_t triangle_count = triangles.size() / 3;

  for (std::size_t t = 0; t < triangle_count; ++t) {
    const Eigen::Vector3d p0 = vertices[triangles[3 * t]].cast<double>();
    const Eigen::Vector3d p1 = vertices[triangles[3 * t + 1]].cast<double>();
    const Eigen::Vector3d p2 = vertices[triangles[3 * t + 2]].cast<double>();
    if (p0.z() < options.near_mm || p1.z() < options.near_mm || p2.z() < options.near_mm) continue;
    // Front-facing when the geometric normal points back towards the camera at the origin.
    if (options.cull_backfaces && (p1 - p0).cross(p2 - p0).dot(p0) >= 0.0) continue;

    const double x0 = k.fx * p0.x() / p0.z() + k.cx, y0 = k.fy * p0.y() / p0.z() + k.cy;
    const double x1 = k.fx * p1.x() / p1.z() + k.cx, y1 = k.fy * p1.y() / p1.z() + k.cy;
    const double x2 = k.fx * p2.x() / p2.z() + k.cx, y2 = k.fy * p2.y() / p2.z() + k.cy;
    // Twice the signed screen area; the edge functions below are divided by it, so either
    // winding works and the weights come out as the screen-space barycentrics l0, l1, l2.
    const double area = (x1 - x0) * (y2 - y0) - (y1 - y0) * (x2 - x0);
    if (std::abs(area) < 1e-12) continue;
    const double inv_area = 1.0 / area;

    const int min_x = std::max(0, static_cast<int>(std::ceil(std::min({x0, x1, x2}))));
    const int max_x = std::min(w - 1, static_cast<int>(std::floor(std::max({x0, x1, x2}))));
    const int min_y = std::max(0, static_cast<int>(std::ceil(std::min({y0, y1, y2}))));
    const int max_y = std::min(h - 1, static_cast<int>(std::floor(std::max({y0, y1, y2}))));
    if (min_x > max_x || min_y > max_y) continue;

    // Perspective-correct interpolation: 1/z is affine in screen space, so
    //   1/z = l0/z0 + l1/z1 + l2/z2 and b_i = (l_i / z_i) * z.
    const double iz0 = 1.0 / p0.z(), iz1 = 1.0 / p1.z(), iz2 = 1.0 / p2.z();
    // Edge function e_i(x, y) opposite vertex i, normalised: l_i = e_i / area.
    const double a0 = (y1 - y2) * inv_area, b0 = (x2 - x1) * inv_area;
    const double a1 = (y2 - y0) * inv_area, b1 = (x0 - x2) * inv_area;
    const double c0 = ((x1 * y2) - (x2 * y1)) * inv_area;
    const double c1 = ((x2 * y0) - (x0 * y2)) * inv_area;
    // A small negative slack keeps pixels exactly on shared edges (l = 0 up to rounding) from
    // falling through both neighbours; the z-test settles double coverage.
    constexpr double kEdgeSlack = -1e-9;
    const auto id = static_cast<std::int32_t>(t) + options.triangle_id_offset;

    for (int y = min_y; y <= max_y; ++y) {
      double l0 = a0 * min_x + b0 * y + c0;
      double l1 = a1 * min_x + b1 * y + c1;
      for (int x = min_x; x <= max_x; ++x, l0 += a0, l1 += a1) {
        const double l2 = 1.0 - l0 - l1;
        if (l0 < kEdgeSlack || l1 < kEdgeSlack || l2 < kEdgeSlack) continue;
        const double inv_z = l0 * iz0 + l1 * iz1 + l2 * iz2;
        const double z = 1.0 / inv_z;
        const std::size_t i = target.index(x, y);
        if (!(z < target.depth[i])) continue;
        target.depth[i] = static_cast<float>(z);
        target.triangle[i] = id;
        target.bary1[i] = static_cast<float>(l1 * iz1 * z);
        target.bary2[i] = static_cast<float>(l2 * iz2 * z);
      }
    }
  }
  return success();
}

}  // namespace fb
