// The expression ratio image and the per-region light (issue 40 round 5) on known truth: a
// sheet of skin seen head-on whose albedo varies 3x more than the relief's shading; the
// expression moves the skin 3.5 mm up and stretches it 3 % sideways, and adds grooves. Dividing
// by the neutral warped through the two meshes must give back the grooves' shading.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <vector>

#include "algo/render/rasterizer.hpp"
#include "algo/wrinkles/expression_ratio.hpp"

namespace fb {
namespace {

PinholeIntrinsics camera() {
  PinholeIntrinsics k;
  k.fx = k.fy = 580.0;  // 1.2 mm per pixel at 700 mm, the booth's colour frame
  k.cx = 319.5;
  k.cy = 239.5;
  return k;
}

// A 140 x 110 mm sheet at 700 mm, 2 mm cells (the face mesh's spacing).
struct Sheet {
  std::vector<Eigen::Vector3f> vertices;
  std::vector<std::uint32_t> triangles;
};

Sheet sheet(float shift_y, float stretch_x) {
  Sheet s;
  const int nx = 71, ny = 56;
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i)
      s.vertices.emplace_back(stretch_x * (-70.0f + 2.0f * i), -55.0f + 2.0f * j + shift_y, 700.0f);
  for (int j = 0; j + 1 < ny; ++j)
    for (int i = 0; i + 1 < nx; ++i) {
      const auto a = static_cast<std::uint32_t>(j * nx + i), b = a + 1, c = a + nx, d = c + 1;
      s.triangles.insert(s.triangles.end(), {a, b, c, b, d, c});
    }
  return s;
}

// The skin's albedo and the expression's relief shading, both at a point of the neutral sheet.
float albedo(float x, float y) {
  return 0.6f *
         (1.0f + 0.15f * std::sin(0.55f * x + 0.8f * std::sin(0.3f * y)) * std::cos(0.5f * y));
}
float relief_shading(float, float y) {
  float s = 1.0f;
  for (int k = -3; k <= 3; ++k) {
    const float d = (y - 7.0f * k) / 1.6f;
    s -= 0.05f * std::exp(-0.5f * d * d);
  }
  return s;
}

// The sheet's image: per pixel the point of the neutral sheet seen there, and its luminance.
FloatImage render(const Sheet& seen, const Sheet& neutral, bool relief, RasterBuffers& raster) {
  const PinholeIntrinsics k = camera();
  raster.reset(k.width, k.height);
  RasterOptions ro;
  ro.cull_backfaces = false;
  EXPECT_TRUE(rasterize(k, seen.vertices, seen.triangles, ro, raster));
  FloatImage out;
  out.resize(k.width, k.height);
  for (int y = 0; y < k.height; ++y)
    for (int x = 0; x < k.width; ++x) {
      const std::size_t i = raster.index(x, y);
      out.at(x, y) = 0.0f;
      const std::int32_t t = raster.triangle[i];
      if (t == kNoTriangle) continue;
      const float b1 = raster.bary1[i], b2 = raster.bary2[i], b0 = 1 - b1 - b2;
      const auto* tri = &neutral.triangles[3 * static_cast<std::size_t>(t)];
      const Eigen::Vector3f m = b0 * neutral.vertices[tri[0]] + b1 * neutral.vertices[tri[1]] +
                                b2 * neutral.vertices[tri[2]];
      out.at(x, y) = albedo(m.x(), m.y()) * (relief ? relief_shading(m.x(), m.y()) : 1.0f);
    }
  return out;
}

double correlation(const std::vector<double>& a, const std::vector<double>& b) {
  double sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0;
  const double n = static_cast<double>(a.size());
  for (std::size_t i = 0; i < a.size(); ++i)
    sa += a[i], sb += b[i], saa += a[i] * a[i], sbb += b[i] * b[i], sab += a[i] * b[i];
  return (sab - sa * sb / n) / std::sqrt((saa - sa * sa / n) * (sbb - sb * sb / n));
}

TEST(ExpressionRatio, DividingByTheWarpedNeutralRecoversTheReliefShading) {
  const Sheet neutral = sheet(0.0f, 1.0f), expression = sheet(-3.5f, 1.03f);
  RasterBuffers rn, re;
  const FloatImage neutral_image = render(neutral, neutral, false, rn);
  const FloatImage expression_image = render(expression, neutral, true, re);
  for (const bool cubic : {false, true}) {
    auto warped =
        warp_neutral(camera(), re, {neutral.vertices, neutral.triangles}, neutral_image, cubic);
    ASSERT_TRUE(warped) << warped.error().message;
    const FloatImage ratio = ratio_image(expression_image, *warped);
    std::vector<double> truth, got, raw;
    double worst = 0.0;
    // The middle of the sheet (its image spans about x 262-377, y 193-282 before the move).
    for (int y = 205; y < 270; ++y)
      for (int x = 270; x < 370; ++x) {
        const std::size_t i = re.index(x, y);
        ASSERT_NE(re.triangle[i], kNoTriangle);
        const float b1 = re.bary1[i], b2 = re.bary2[i], b0 = 1 - b1 - b2;
        const auto* tri = &neutral.triangles[3 * static_cast<std::size_t>(re.triangle[i])];
        const Eigen::Vector3f m = b0 * neutral.vertices[tri[0]] + b1 * neutral.vertices[tri[1]] +
                                  b2 * neutral.vertices[tri[2]];
        truth.push_back(relief_shading(m.x(), m.y()));
        got.push_back(ratio.at(x, y) / 0.5);
        raw.push_back(expression_image.at(x, y));
        worst = std::max(worst, std::abs(got.back() - truth.back()));
      }
    std::printf("%s: frame vs relief shading corr %.3f; ratio corr %.3f, worst %.4f\n",
                cubic ? "Catmull-Rom" : "bilinear", correlation(raw, truth),
                correlation(got, truth), worst);
    // The albedo hides the relief in the frame; the ratio shows it.
    EXPECT_LT(std::abs(correlation(raw, truth)), 0.45) << cubic;
    // The relief's lines are 0.05 deep; bilinear sampling smooths the neutral's albedo a little
    // (measured 0.973, worst 0.012), Catmull-Rom hardly (1.000, 0.0015).
    EXPECT_GT(correlation(got, truth), cubic ? 0.99 : 0.96);
    EXPECT_LT(worst, cubic ? 0.005 : 0.02);
  }
}

TEST(ExpressionRatio, OffTheMeshTheFrameIsKept) {
  const Sheet neutral = sheet(0.0f, 1.0f);
  RasterBuffers rn;
  const FloatImage image = render(neutral, neutral, false, rn);
  auto warped = warp_neutral(camera(), rn, {neutral.vertices, neutral.triangles}, image);
  ASSERT_TRUE(warped);
  EXPECT_EQ(warped->at(5, 5), 0.0f);
  const FloatImage ratio = ratio_image(image, *warped);
  EXPECT_EQ(ratio.at(5, 5), image.at(5, 5));
  EXPECT_NEAR(ratio.at(320, 240), 0.5f, 1e-5f);  // the neutral over itself: mid-grey
}

TEST(ExpressionRatio, RegionNormalAndLocalLight) {
  // The sheet turned 20 degrees about x, its top away from the camera (a forehead).
  Sheet s = sheet(0.0f, 1.0f);
  const float a = 20.0f * static_cast<float>(M_PI) / 180.0f;
  for (auto& v : s.vertices) {
    const float y = v.y(), z = v.z() - 700.0f;
    v.y() = std::cos(a) * y + std::sin(a) * z;
    v.z() = 700.0f - std::sin(a) * y + std::cos(a) * z;
  }
  RasterBuffers r;
  r.reset(640, 480);
  RasterOptions ro;
  ro.cull_backfaces = false;
  ASSERT_TRUE(rasterize(camera(), s.vertices, s.triangles, ro, r));
  const std::vector<PixelRect> regions = {PixelRect::from_size(300, 220, 40, 30),
                                          PixelRect::from_size(0, 0, 10, 10)};
  const auto n = region_normals(r, {s.vertices, s.triangles}, regions);
  ASSERT_EQ(n.size(), 2u);
  // The plane's normal towards the camera: (0, -sin a, -cos a) with y down (its top recedes).
  EXPECT_NEAR(n[0].x(), 0.0f, 1e-4f);
  EXPECT_NEAR(n[0].y(), -std::sin(a), 1e-4f);
  EXPECT_NEAR(n[0].z(), -std::cos(a), 1e-4f);
  EXPECT_EQ(n[1], Eigen::Vector3f(0.0f, 0.0f, -1.0f));  // off the mesh

  // Facing the camera, the booth's light is SkinLight's default.
  const Eigen::Vector3f booth = Eigen::Vector3f(-0.35f, -0.45f, -1.0f).normalized();
  const SkinLight facing = skin_light_for(Eigen::Vector3f(0, 0, -1), booth);
  EXPECT_LT((facing.to_light - SkinLight{}.to_light).norm(), 1e-5f);
  // Turned up into the light: more of it along the normal, less along the patch's "down".
  const SkinLight up = skin_light_for(n[0], booth);
  EXPECT_NEAR(up.to_light.norm(), 1.0f, 1e-5f);
  EXPECT_NEAR(up.to_light.z(), booth.dot(n[0]), 1e-5f);
  EXPECT_GT(up.to_light.z(), facing.to_light.z());
  EXPECT_NEAR(up.to_light.x(), facing.to_light.x(), 1e-5f);
  EXPECT_GT(up.to_light.y(), facing.to_light.y());  // less from above, seen on the patch
}

}  // namespace
}  // namespace fb
