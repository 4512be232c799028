// Per-sample geometry the tracker's engines share: the depth camera in float (projection, its
// Jacobian, bilinear depth lookup) and the Tukey biweight. Everything here is called per sample
// in the hot loops, so it stays inline in this header: the engines live in separate files, and
// an out-of-line call per sample cost about 0.1 ms a frame when the tracker was first split.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>

#include <Eigen/Core>

#include "algo/core/camera_model.hpp"
#include "algo/core/image.hpp"
#include "algo/tracking/depth_smoother.hpp"

namespace fb {

// Tukey biweight: (1 - (r/c)^2)^2 inside the cut-off, 0 outside.
inline float tukey(float r, float c) {
  const float u = r / c;
  if (u * u >= 1.0f) return 0.0f;
  const float s = 1.0f - u * u;
  return s * s;
}

struct TrackerCamera {
  float fx = 0, fy = 0, cx = 0, cy = 0;
  int width = 0, height = 0;

  static TrackerCamera from(const PinholeIntrinsics& k) {
    return {static_cast<float>(k.fx),
            static_cast<float>(k.fy),
            static_cast<float>(k.cx),
            static_cast<float>(k.cy),
            k.width,
            k.height};
  }
  PixelRect full() const { return {0, 0, width, height}; }
  // The pixel (u, v) the camera-frame point x (z > 0) projects to.
  Eigen::Vector2f pixel_of(const Eigen::Vector3f& x) const {
    return {fx * x.x() / x.z() + cx, fy * x.y() / x.z() + cy};
  }
  // The camera-frame point at depth z on the ray through pixel px.
  Eigen::Vector3f ray_point(const Eigen::Vector2f& px, float z) const {
    return {(px.x() - cx) * z / fx, (px.y() - cy) * z / fy, z};
  }
  // d proj / d x at the camera-frame point x (2x3): the point's image motion per unit motion.
  Eigen::Matrix<float, 2, 3> projection_jacobian(const Eigen::Vector3f& x) const {
    const float iz = 1.0f / x.z();
    Eigen::Matrix<float, 2, 3> j;
    j << fx * iz, 0.0f, -fx * x.x() * iz * iz, 0.0f, fy * iz, -fy * x.y() * iz * iz;
    return j;
  }
  // Depth at (u, v) inside b: bilinear between the 4 pixel centres around it when all are
  // valid and on one surface.
  bool depth_at(const Image<float>& image, const PixelRect& b, float u, float v, float& z) const {
    const int x0 = static_cast<int>(std::floor(u)), y0 = static_cast<int>(std::floor(v));
    if (x0 < b.x0 || y0 < b.y0 || x0 + 1 >= b.x1 || y0 + 1 >= b.y1) return false;
    const float* row0 = &image.pixels[static_cast<std::size_t>(y0) * width + x0];
    const float* row1 = row0 + width;
    const float d00 = row0[0], d10 = row0[1], d01 = row1[0], d11 = row1[1];
    if (d00 <= 0.0f || d10 <= 0.0f || d01 <= 0.0f || d11 <= 0.0f) return false;
    const float lo = std::min(std::min(d00, d10), std::min(d01, d11));
    const float hi = std::max(std::max(d00, d10), std::max(d01, d11));
    if (hi - lo > 12.0f) return false;
    const float ax = u - x0, ay = v - y0;
    z = (1 - ay) * ((1 - ax) * d00 + ax * d10) + ay * ((1 - ax) * d01 + ax * d11);
    return true;
  }
  // The measured point q on the camera ray through x (depth_at() at x's pixel), if any.
  bool measured_point(const Image<float>& image, const PixelRect& b, const Eigen::Vector3f& x,
                      Eigen::Vector3f& q) const {
    float z = 0.0f;
    const Eigen::Vector2f px = pixel_of(x);
    if (!depth_at(image, b, px.x(), px.y(), z)) return false;
    q = x * (z / x.z());
    return true;
  }
};

}  // namespace fb
