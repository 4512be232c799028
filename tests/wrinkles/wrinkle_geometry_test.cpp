// Wrinkle heights onto the mesh and into the UV layout, against a plane seen head-on whose
// heights, slopes and borders are known.
#include <gtest/gtest.h>

#include <cmath>

#include "algo/wrinkles/wrinkle_geometry.hpp"

namespace fb {
namespace {

// A 41 x 41 vertex plane, 1 mm apart, z = 0 facing +z, UVs its (x, y) over [0, 1]; 0.5 m in
// front of a 200 x 200 camera (f 400 px): model x -> image x, model y -> image -y, 0.8 px/mm.
struct Plane {
  std::vector<float> vertices, uvs;
  std::vector<std::uint32_t> triangles;
  HeightView view;
  FloatImage height;
  Image<std::uint8_t> domain;
  int index(int i, int j) const { return j * 41 + i; }
};

Plane make_plane(float (*height_at_pixel)(int, int)) {
  Plane p;
  for (int j = 0; j <= 40; ++j)
    for (int i = 0; i <= 40; ++i) {
      p.vertices.insert(p.vertices.end(), {i - 20.0f, j - 20.0f, 0.0f});
      p.uvs.insert(p.uvs.end(), {i / 40.0f, j / 40.0f});
    }
  for (int j = 0; j < 40; ++j)
    for (int i = 0; i < 40; ++i) {
      const auto a = static_cast<std::uint32_t>(p.index(i, j)), b = a + 1, c = a + 41, d = c + 1;
      p.triangles.insert(p.triangles.end(), {a, b, d, a, d, c});
    }
  p.height.resize(200, 200);
  p.domain.resize(200, 200);
  for (int y = 0; y < 200; ++y)
    for (int x = 0; x < 200; ++x) {
      const bool in = x >= 92 && x <= 108 && y >= 92 && y <= 108;  // model |x|, |y| <= 10 mm
      p.domain.at(x, y) = in;
      p.height.at(x, y) = in ? height_at_pixel(x, y) : 0.0f;
    }
  p.view.height_mm = &p.height;
  p.view.domain = &p.domain;
  p.view.camera_from_model.rotation = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX());
  p.view.camera_from_model.translation = {0, 0, 500};
  p.view.intrinsics = {200, 200, 400, 400, 100, 100};
  return p;
}

TEST(WrinkleGeometry, VerticesTakeTheHeightTheyShowAndBordersAreSmoothed) {
  const Plane p = make_plane([](int, int) { return -0.5f; });
  const std::vector<float> h = vertex_heights(p.vertices, p.triangles, p.view);
  EXPECT_NEAR(h[p.index(20, 20)], -0.5f, 1e-5);
  EXPECT_EQ(h[p.index(2, 20)], 0.0f);  // outside the domain
  EXPECT_EQ(h[p.index(20, 35)], 0.0f);
  const std::vector<float> moved = displace_mesh(p.vertices, p.triangles, h);
  auto z = [&](int i, int j) { return moved[3 * p.index(i, j) + 2]; };
  EXPECT_NEAR(z(20, 20), -0.5f, 1e-5);  // inside, away from the border: the full height
  EXPECT_EQ(z(2, 20), 0.0f);            // far outside: untouched
  // Across the border at x = +-10 mm the step is smoothed into a monotone ramp.
  for (int i = 24; i < 34; ++i) EXPECT_LE(z(i, 20), z(i + 1, 20) + 1e-6f) << i;
  EXPECT_GT(z(30, 20), -0.45f);
  EXPECT_LT(z(30, 20), -0.05f);
  EXPECT_EQ(moved[3 * p.index(20, 20)], p.vertices[3 * p.index(20, 20)]);  // along the normal
}

TEST(WrinkleGeometry, DetailMapsCarryTheHeightAndItsSlope) {
  // A ramp of 0.2 mm per pixel along image x: 0.16 mm per mm along model x (= +u).
  const Plane p = make_plane([](int x, int) { return 0.2f * (x - 100); });
  const auto map = make_texel_map(p.uvs, p.triangles, 64, 64);
  ASSERT_TRUE(map.ok());
  const auto maps = detail_maps(*map, p.uvs, p.triangles, p.vertices, p.triangles, p.view);
  ASSERT_TRUE(maps.ok()) << maps.error().message;
  // Texel (32, 32) is u, v = 0.5078: model (0.31, 0.31) mm, image x 100.25.
  EXPECT_NEAR(maps->displacement_mm.at(32, 32), 0.2f * 0.25f, 0.03f);
  EXPECT_EQ(maps->displacement_mm.at(5, 5), 0.0f);
  // Normal tilted against +u by atan(0.16): x = -0.158 -> 107; y flat -> 128.
  const Rgb8 n = maps->normal_map.at(32, 32);
  EXPECT_NEAR(n.r, 107, 3);
  EXPECT_NEAR(n.g, 128, 2);
  EXPECT_GT(n.b, 250);
  EXPECT_EQ(maps->normal_map.at(5, 5).r, 128);
  EXPECT_GT(maps->texels_with_detail, 100);
}

TEST(WrinkleGeometry, MismatchedLayoutIsAnError) {
  const Plane p = make_plane([](int, int) { return 0.0f; });
  const auto map = make_texel_map(p.uvs, p.triangles, 64, 64);
  ASSERT_TRUE(map.ok());
  const std::vector<std::uint32_t> short_layout(p.triangles.begin(), p.triangles.end() - 3);
  EXPECT_FALSE(detail_maps(*map, p.uvs, short_layout, p.vertices, p.triangles, p.view).ok());
}

}  // namespace
}  // namespace fb
