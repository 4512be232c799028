#include "algo/render/rasterizer.hpp"

#include <cmath>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>

namespace fb {
namespace {

PinholeIntrinsics test_intrinsics() {
  PinholeIntrinsics k;
  k.width = 160;
  k.height = 120;
  k.fx = k.fy = 150.0;
  k.cx = 79.5;
  k.cy = 59.5;
  return k;
}

// A square plane at depth z facing the camera (counter-clockwise seen from the camera, which
// with y down means clockwise in (x, y)... checked by the culling test below).
void add_plane(float half, float z, std::vector<Eigen::Vector3f>& v,
               std::vector<std::uint32_t>& t) {
  const auto base = static_cast<std::uint32_t>(v.size());
  v.emplace_back(-half, -half, z);
  v.emplace_back(half, -half, z);
  v.emplace_back(half, half, z);
  v.emplace_back(-half, half, z);
  // Front faces have (p1 - p0) x (p2 - p0) pointing to -z (towards the camera).
  for (std::uint32_t i : {0u, 2u, 1u, 0u, 3u, 2u}) t.push_back(base + i);
}

TEST(Rasterizer, PlaneAtKnownDepthRendersExactly) {
  std::vector<Eigen::Vector3f> v;
  std::vector<std::uint32_t> t;
  add_plane(5000.0f, 1234.5f, v, t);
  RasterBuffers buffers;
  const auto k = test_intrinsics();
  buffers.reset(k.width, k.height);
  ASSERT_TRUE(rasterize(k, v, t, {}, buffers).ok());
  for (int y = 0; y < k.height; ++y) {
    for (int x = 0; x < k.width; ++x) {
      ASSERT_TRUE(buffers.covered(x, y)) << x << "," << y;
      ASSERT_NEAR(buffers.depth[buffers.index(x, y)], 1234.5f, 1e-3f);
    }
  }
}

TEST(Rasterizer, TiltedPlaneDepthIsPerspectiveCorrect) {
  // Plane z = 1000 + 0.5 x: along a pixel ray (u, v) the depth is 1000 / (1 - 0.5 (u - cx)/fx).
  std::vector<Eigen::Vector3f> v;
  std::vector<std::uint32_t> t;
  const float half = 800.0f;
  v.emplace_back(-half, -half, 1000.0f - 0.5f * half);
  v.emplace_back(half, -half, 1000.0f + 0.5f * half);
  v.emplace_back(half, half, 1000.0f + 0.5f * half);
  v.emplace_back(-half, half, 1000.0f - 0.5f * half);
  t = {0, 2, 1, 0, 3, 2};
  RasterBuffers buffers;
  const auto k = test_intrinsics();
  buffers.reset(k.width, k.height);
  ASSERT_TRUE(rasterize(k, v, t, {}, buffers).ok());
  for (int y = 0; y < k.height; y += 7) {
    for (int x = 0; x < k.width; x += 5) {
      ASSERT_TRUE(buffers.covered(x, y));
      const double expected = 1000.0 / (1.0 - 0.5 * (x - k.cx) / k.fx);
      EXPECT_NEAR(buffers.depth[buffers.index(x, y)], expected, 1e-2);
    }
  }
}

TEST(Rasterizer, BackfacesAreCulledAndIdsOffset) {
  std::vector<Eigen::Vector3f> v;
  std::vector<std::uint32_t> t;
  add_plane(100.0f, 500.0f, v, t);
  std::vector<std::uint32_t> reversed = {0, 1, 2, 0, 2, 3};
  const auto k = test_intrinsics();
  RasterBuffers buffers;
  buffers.reset(k.width, k.height);
  ASSERT_TRUE(rasterize(k, v, reversed, {}, buffers).ok());
  for (auto id : buffers.triangle) EXPECT_EQ(id, kNoTriangle);
  RasterOptions no_cull;
  no_cull.cull_backfaces = false;
  no_cull.triangle_id_offset = 10;
  ASSERT_TRUE(rasterize(k, v, reversed, no_cull, buffers).ok());
  EXPECT_TRUE(buffers.triangle[buffers.index(80, 60)] == 10 ||
              buffers.triangle[buffers.index(80, 60)] == 11);
}

TEST(Rasterizer, NearerSurfaceWinsAndBarycentricsReproducePosition) {
  std::vector<Eigen::Vector3f> v;
  std::vector<std::uint32_t> t;
  add_plane(2000.0f, 1500.0f, v, t);
  add_plane(60.0f, 700.0f, v, t);
  const auto k = test_intrinsics();
  RasterBuffers buffers;
  buffers.reset(k.width, k.height);
  ASSERT_TRUE(rasterize(k, v, t, {}, buffers).ok());
  EXPECT_NEAR(buffers.depth[buffers.index(80, 60)], 700.0f, 1e-3f);
  EXPECT_NEAR(buffers.depth[buffers.index(2, 2)], 1500.0f, 1e-3f);
  // Interpolating vertex positions with the barycentrics gives the 3D point on the pixel ray.
  for (int y = 0; y < k.height; y += 11) {
    for (int x = 0; x < k.width; x += 13) {
      const auto i = buffers.index(x, y);
      const auto id = static_cast<std::size_t>(buffers.triangle[i]);
      const float b1 = buffers.bary1[i], b2 = buffers.bary2[i];
      const Eigen::Vector3f p =
          (1 - b1 - b2) * v[t[3 * id]] + b1 * v[t[3 * id + 1]] + b2 * v[t[3 * id + 2]];
      const Eigen::Vector3d expected = k.unproject(x, y, buffers.depth[i]);
      EXPECT_NEAR((p.cast<double>() - expected).norm(), 0.0, 1e-2) << x << "," << y;
    }
  }
}

TEST(Rasterizer, SphereDepthMatchesAnalytic) {
  // UV sphere, radius 100 mm, centre at 800 mm; compare with the ray-sphere intersection.
  const double radius = 100.0, centre_z = 800.0;
  const int rings = 96, segments = 192;
  std::vector<Eigen::Vector3f> v;
  std::vector<std::uint32_t> t;
  for (int r = 0; r <= rings; ++r) {
    const double theta = std::numbers::pi * r / rings;
    for (int s = 0; s < segments; ++s) {
      const double phi = 2 * std::numbers::pi * s / segments;
      v.emplace_back(radius * std::sin(theta) * std::cos(phi), radius * std::cos(theta),
                     centre_z + radius * std::sin(theta) * std::sin(phi));
    }
  }
  for (int r = 0; r < rings; ++r) {
    for (int s = 0; s < segments; ++s) {
      const std::uint32_t a = r * segments + s, b = r * segments + (s + 1) % segments;
      const std::uint32_t c = a + segments, d = b + segments;
      t.insert(t.end(), {a, b, d, a, d, c});
    }
  }
  const auto k = test_intrinsics();
  RasterBuffers buffers;
  buffers.reset(k.width, k.height);
  // Winding of this parameterisation is not checked here, so draw both sides; the z-test keeps
  // the near half.
  RasterOptions options;
  options.cull_backfaces = false;
  ASSERT_TRUE(rasterize(k, v, t, options, buffers).ok());
  int compared = 0;
  double max_error = 0.0;
  for (int y = 0; y < k.height; ++y) {
    for (int x = 0; x < k.width; ++x) {
      const Eigen::Vector3d ray = k.unproject(x, y, 1.0);
      // |s ray - c|^2 = R^2 -> s^2 |ray|^2 - 2 s ray.c + |c|^2 - R^2 = 0, nearest root.
      const Eigen::Vector3d c(0, 0, centre_z);
      const double a2 = ray.squaredNorm(), b2 = ray.dot(c), c2 = c.squaredNorm() - radius * radius;
      const double disc = b2 * b2 - a2 * c2;
      const bool hit = disc > 0.0;
      if (!hit) continue;
      const double s = (b2 - std::sqrt(disc)) / a2;
      // Stay away from the silhouette, where facets and the true sphere differ most.
      if (disc < 0.3 * a2 * radius * radius) continue;
      ASSERT_TRUE(buffers.covered(x, y));
      max_error = std::max(max_error, std::abs(buffers.depth[buffers.index(x, y)] - s));
      ++compared;
    }
  }
  EXPECT_GT(compared, 500);
  // Chord error of a 96 x 192 sphere of radius 100: R (1 - cos(pi/192)) ~ 0.013 mm.
  EXPECT_LT(max_error, 0.1);
}

TEST(Rasterizer, BadIndexIsAnError) {
  std::vector<Eigen::Vector3f> v(3, Eigen::Vector3f(0, 0, 500));
  std::vector<std::uint32_t> t = {0, 1, 3};
  RasterBuffers buffers;
  buffers.reset(10, 10);
  auto result = rasterize(test_intrinsics(), v, t, {}, buffers);
  ASSERT_FALSE(result.ok());
  EXPECT_NE(result.error().message.find("out of range"), std::string::npos);
}

}  // namespace
}  // namespace fb
