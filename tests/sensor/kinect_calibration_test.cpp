#include "algo/sensor/kinect_calibration.hpp"

#include <cmath>
#include <cstdlib>

#include <gtest/gtest.h>

namespace fb {
namespace {

class KinectRegistrationTest : public ::testing::Test {
 protected:
  KinectRegistration reg{KinectCalibration::defaults()};
};

TEST_F(KinectRegistrationTest, RawToMmMatchesLibfreenectFormula) {
  // freenect_raw_to_mm by hand for raw 966 (a pixel of the openiss-desk dump):
  // fixed_ref_x = (966 - 4*200)/4 - 0.375 = 41.125; metric = 41.125 * 0.1042;
  // mm = 10 * (metric * 120 / (7.5 - metric) + 120).
  const double metric = 41.125 * 0.10419999808073044;
  const double expected = 10.0 * (metric * 120.0 / (7.5 - metric) + 120.0);
  // Rounded (libfreenect truncates, which puts every depth 0.5 mm nearer on average).
  EXPECT_EQ(reg.raw_to_mm(966), static_cast<std::uint16_t>(std::lround(expected)));
  EXPECT_NEAR(reg.raw_to_mm_exact(966), expected, 1e-3);
  EXPECT_NEAR(reg.raw_to_mm(966), 2800, 20);
}

TEST(RegistrationCorrection, IdentityKeepsLibfreenectsTables) {
  const KinectRegistration plain(KinectCalibration::defaults());
  KinectCalibration c = KinectCalibration::defaults();
  c.correction.dx_px = 0.0;
  const KinectRegistration same(c);
  for (int y = 0; y < 480; y += 37)
    for (int x = 0; x < 640; x += 41) {
      double ax = 0, ay = 0, bx = 0, by = 0;
      const bool a = plain.depth_to_color(x, y, 800, ax, ay);
      ASSERT_EQ(a, same.depth_to_color(x, y, 800, bx, by));
      if (!a) continue;
      EXPECT_EQ(ax, bx);
      EXPECT_EQ(ay, std::floor(ay)) << "rows stay whole under an identity correction";
    }
}

TEST(RegistrationCorrection, ShiftsRotatesAndScales) {
  const KinectRegistration plain(KinectCalibration::defaults());
  KinectCalibration c = KinectCalibration::defaults();
  c.correction.dx_px = 7.5;
  c.correction.dy_px = -13.25;
  c.correction.rotation_deg = 0.5;
  c.correction.depth_scale = 1.04;
  const KinectRegistration corrected(c);
  // At the centre the rotation moves nothing: the shift alone (within the 1/256 px table).
  double ax = 0, ay = 0, bx = 0, by = 0;
  ASSERT_TRUE(plain.depth_to_color(320, 240, 900, ax, ay));
  ASSERT_TRUE(corrected.depth_to_color(320, 240, 900, bx, by));
  EXPECT_NEAR(bx - ax, 7.5, 0.05);
  EXPECT_NEAR(by - ay, -13.25, 0.05);
  // 200 px right of the centre a 0.5 deg rotation moves the row down by 200 sin(0.5 deg).
  ASSERT_TRUE(plain.depth_to_color(520, 240, 900, ax, ay));
  ASSERT_TRUE(corrected.depth_to_color(520, 240, 900, bx, by));
  EXPECT_NEAR(by - ay, -13.25 + 200 * std::sin(0.5 * 3.14159265358979 / 180), 0.1);
  // The depth law: 4 % longer, rounded.
  EXPECT_NEAR(corrected.raw_to_mm(700), plain.raw_to_mm_exact(700) * 1.04, 0.51);
  // mm_to_raw inverts the corrected law.
  EXPECT_NEAR(corrected.mm_to_raw(corrected.raw_to_mm(700)), 700, 1);
}

TEST_F(KinectRegistrationTest, InvalidRawIsZero) {
  EXPECT_EQ(reg.raw_to_mm(kInvalidDisparity), 0);
  EXPECT_EQ(reg.raw_to_mm(2047), 0);
  EXPECT_EQ(reg.raw_to_mm(5000), 0);
  EXPECT_EQ(reg.mm_to_raw(0), kInvalidDisparity);
  EXPECT_EQ(reg.mm_to_raw(20000), kInvalidDisparity);
  EXPECT_EQ(reg.mm_to_raw(50), kInvalidDisparity);  // closer than the sensor can see
}

TEST_F(KinectRegistrationTest, RawToMmIsMonotonicOverValidRange) {
  int valid = 0;
  std::uint16_t previous = 0;
  bool ended = false;
  for (int raw = 0; raw < 2047; ++raw) {
    const std::uint16_t mm = reg.raw_to_mm(static_cast<std::uint16_t>(raw));
    if (mm == 0) {
      if (valid > 0) ended = true;
      continue;
    }
    EXPECT_FALSE(ended) << "valid depth after the end of the valid run at raw " << raw;
    EXPECT_GE(mm, previous) << "raw " << raw;
    previous = mm;
    ++valid;
  }
  // About 0.3 m to 10 m is covered by roughly raw 0..1050.
  EXPECT_GT(valid, 1000);
  EXPECT_LT(reg.raw_to_mm(0), 400);
  EXPECT_GT(previous, 9000);
}

TEST_F(KinectRegistrationTest, RawRoundTripIsExactOnDepthValues) {
  for (int raw = 0; raw < 2047; ++raw) {
    const std::uint16_t mm = reg.raw_to_mm(static_cast<std::uint16_t>(raw));
    if (mm == 0) continue;
    const std::uint16_t back = reg.mm_to_raw(mm);
    ASSERT_NE(back, kInvalidDisparity) << "raw " << raw;
    EXPECT_EQ(reg.raw_to_mm(back), mm) << "raw " << raw;
  }
}

TEST_F(KinectRegistrationTest, QuantizationWithinHalfAStep) {
  // For every reachable depth z, the chosen raw's depth is within half the local step.
  for (int z = 500; z <= 8000; ++z) {
    const std::uint16_t raw = reg.mm_to_raw(static_cast<std::uint16_t>(z));
    ASSERT_NE(raw, kInvalidDisparity) << z;
    const int q = reg.raw_to_mm(raw);
    const int lo = reg.raw_to_mm(static_cast<std::uint16_t>(raw - 1));
    const int hi = reg.raw_to_mm(static_cast<std::uint16_t>(raw + 1));
    const double half_step = 0.5 * std::max(q - lo, hi - q);
    EXPECT_LE(std::abs(q - z), half_step + 1e-9) << "z " << z << " raw " << raw;
  }
}

TEST_F(KinectRegistrationTest, ImageConversionsReuseBuffers) {
  DisparityImage raw;
  raw.resize(640, 480);
  for (std::size_t i = 0; i < raw.pixels.size(); ++i) raw.pixels[i] = 600 + i % 400;
  raw.pixels[0] = kInvalidDisparity;
  DepthImage mm;
  reg.disparity_to_mm(raw, mm);
  ASSERT_EQ(mm.width, 640);
  ASSERT_EQ(mm.height, 480);
  EXPECT_EQ(mm.pixels[0], 0);
  const auto* data = mm.pixels.data();
  reg.disparity_to_mm(raw, mm);
  EXPECT_EQ(mm.pixels.data(), data);
  DisparityImage back;
  reg.mm_to_disparity(mm, back);
  EXPECT_EQ(back.pixels[0], kInvalidDisparity);
  for (std::size_t i = 1; i < raw.pixels.size(); ++i) {
    ASSERT_EQ(reg.raw_to_mm(back.pixels[i]), mm.pixels[i]);
  }
}

TEST_F(KinectRegistrationTest, DepthIntrinsicsFollowCameraToWorld) {
  const PinholeIntrinsics k = reg.depth_intrinsics();
  EXPECT_NEAR(k.fx, 120.0 / (2 * 0.1042), 0.01);
  EXPECT_NEAR(k.fx, 575.8, 0.1);
  EXPECT_EQ(k.fx, k.fy);
  EXPECT_EQ(k.cx, 320.0);
  EXPECT_EQ(k.cy, 240.0);
}

TEST_F(KinectRegistrationTest, RegistrationShiftsWithParallax) {
  // Points far away map close to the rectified position; near points shift by the baseline
  // parallax (about f * 24 mm / z px). The shift between 800 mm and 4000 mm at the centre pixel
  // must be about 575.8 * 24 * (1/800 - 1/4000) / 2... in 640-pixel units.
  double x_near = 0, y_near = 0, x_far = 0, y_far = 0;
  ASSERT_TRUE(reg.depth_to_color(320, 240, 800, x_near, y_near));
  ASSERT_TRUE(reg.depth_to_color(320, 240, 4000, x_far, y_far));
  EXPECT_EQ(y_near, y_far);
  const double expected = 575.8 * 24.0 * (1.0 / 800 - 1.0 / 4000);
  EXPECT_NEAR(std::abs(x_near - x_far), expected, 1.0);
  EXPECT_FALSE(reg.depth_to_color(320, 240, 0, x_near, y_near));

  DepthImage depth;
  depth.resize(640, 480);
  for (auto& p : depth.pixels) p = 1500;
  DepthImage registered;
  reg.register_depth_to_color(depth, registered);
  ASSERT_EQ(registered.width, 640);
  std::size_t filled = 0;
  for (auto p : registered.pixels) {
    EXPECT_TRUE(p == 0 || p == 1500);
    filled += p != 0;
  }
  // A flat wall covers most of the colour image.
  EXPECT_GT(filled, registered.pixels.size() * 8 / 10);
  double cx = 0, cy = 0;
  ASSERT_TRUE(reg.depth_to_color(320, 240, 1500, cx, cy));
  EXPECT_EQ(registered.at(static_cast<int>(cx), static_cast<int>(cy)), 1500);
}

TEST_F(KinectRegistrationTest, NearestSurfaceWins) {
  DepthImage depth;
  depth.resize(640, 480);
  for (auto& p : depth.pixels) p = 3000;
  // A near box in the middle occludes the wall behind it.
  for (int y = 200; y < 280; ++y)
    for (int x = 280; x < 360; ++x) depth.at(x, y) = 900;
  DepthImage registered;
  reg.register_depth_to_color(depth, registered);
  double cx = 0, cy = 0;
  ASSERT_TRUE(reg.depth_to_color(320, 240, 900, cx, cy));
  EXPECT_EQ(registered.at(static_cast<int>(cx), static_cast<int>(cy)), 900);
}

}  // namespace
}  // namespace fb
