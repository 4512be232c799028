#include "algo/render/kinect_sensor.hpp"

#include <cmath>
#include <vector>

#include <gtest/gtest.h>

namespace fb {
namespace {

// Axis-aligned rectangle at depth z facing the camera (front side towards -z).
void add_rect(float x0, float y0, float x1, float y1, float z, std::vector<Eigen::Vector3f>& v,
              std::vector<std::uint32_t>& t) {
  const auto base = static_cast<std::uint32_t>(v.size());
  v.emplace_back(x0, y0, z);
  v.emplace_back(x1, y0, z);
  v.emplace_back(x1, y1, z);
  v.emplace_back(x0, y1, z);
  for (std::uint32_t i : {0u, 2u, 1u, 0u, 3u, 2u}) t.push_back(base + i);
}

// Rectangle through the origin line x = 0, tilted about the y axis by `deg` (0 = facing the
// camera), centred at depth z.
void add_tilted(double deg, float z, std::vector<Eigen::Vector3f>& v,
                std::vector<std::uint32_t>& t) {
  const double c = std::cos(deg * M_PI / 180.0), s = std::sin(deg * M_PI / 180.0);
  const float h = 400.0f;
  const auto base = static_cast<std::uint32_t>(v.size());
  for (auto [x, y] : {std::pair{-h, -h}, {h, -h}, {h, h}, {-h, h}}) {
    v.emplace_back(static_cast<float>(x * c), y, static_cast<float>(z + x * s));
  }
  for (std::uint32_t i : {0u, 2u, 1u, 0u, 3u, 2u}) t.push_back(base + i);
}

class KinectSensorTest : public ::testing::Test {
 protected:
  KinectRegistration registration{KinectCalibration::defaults()};

  // Mean |depth_mm - noiseless| over measured pixels of a frontal wall at depth z.
  double plane_error(float z, KinectSensorOptions options, std::uint64_t seed = 1) {
    std::vector<Eigen::Vector3f> v;
    std::vector<std::uint32_t> t;
    add_rect(-3000, -3000, 3000, 3000, z, v, t);
    KinectSensorModel model(registration, options);
    SensorFrame frame;
    EXPECT_TRUE(model.capture(v, t, seed, frame).ok());
    double sum = 0.0;
    long n = 0;
    for (std::size_t i = 0; i < frame.depth_mm.pixels.size(); ++i) {
      if (frame.depth_mm.pixels[i] == 0) continue;
      sum += std::abs(frame.depth_mm.pixels[i] - frame.noiseless_depth_mm.pixels[i]);
      ++n;
    }
    EXPECT_GT(n, 250000);
    return sum / std::max(n, 1L);
  }
};

TEST_F(KinectSensorTest, NoiselessOutputIsQuantisedRenderedDepth) {
  KinectSensorOptions options;
  options.depth_noise = false;
  std::vector<Eigen::Vector3f> v;
  std::vector<std::uint32_t> t;
  add_tilted(40.0, 900.0f, v, t);
  KinectSensorModel model(registration, options);
  SensorFrame frame;
  ASSERT_TRUE(model.capture(v, t, 7, frame).ok());
  long measured = 0;
  for (std::size_t i = 0; i < frame.depth_mm.pixels.size(); ++i) {
    if (frame.depth_mm.pixels[i] == 0) continue;
    ++measured;
    const auto mm = static_cast<std::uint16_t>(std::lround(frame.noiseless_depth_mm.pixels[i]));
    ASSERT_EQ(frame.raw.pixels[i], registration.mm_to_raw(mm));
    ASSERT_EQ(frame.depth_mm.pixels[i], registration.raw_to_mm(registration.mm_to_raw(mm)));
  }
  EXPECT_GT(measured, 100000);
}

TEST_F(KinectSensorTest, EveryDepthIsTheConversionOfAnIntegerRaw) {
  std::vector<Eigen::Vector3f> v;
  std::vector<std::uint32_t> t;
  add_tilted(50.0, 1100.0f, v, t);
  add_rect(-100, -100, 100, 100, 700, v, t);
  KinectSensorModel model(registration, {});
  SensorFrame frame;
  ASSERT_TRUE(model.capture(v, t, 3, frame).ok());
  for (std::size_t i = 0; i < frame.depth_mm.pixels.size(); ++i) {
    const auto raw = frame.raw.pixels[i];
    if (raw == kInvalidDisparity) {
      ASSERT_EQ(frame.depth_mm.pixels[i], 0);
      ASSERT_NE(frame.invalid.pixels[i], 0);
    } else {
      ASSERT_LT(raw, 2048);
      ASSERT_EQ(frame.depth_mm.pixels[i], registration.raw_to_mm(raw));
      ASSERT_EQ(frame.invalid.pixels[i], 0);
    }
  }
}

TEST_F(KinectSensorTest, NoiseMatchesTargetAndGrowsAsDepthSquared) {
  const double e700 = plane_error(700.0f, {});
  const double e1000 = plane_error(1000.0f, {});
  RecordProperty("mae_700", std::to_string(e700));
  RecordProperty("mae_1000", std::to_string(e1000));
  std::printf("plane mean abs error: %.3f mm at 700, %.3f mm at 1000 (ratio %.2f, z^2 law %.2f)\n",
              e700, e1000, e1000 / e700, (1000.0 * 1000.0) / (700.0 * 700.0));
  EXPECT_GE(e700, 1.0);
  EXPECT_LE(e700, 2.0);
  // Disparity noise maps to depth noise ~ z^2: (1000/700)^2 = 2.04.
  EXPECT_NEAR(e1000 / e700, 2.04, 0.3);
}

TEST_F(KinectSensorTest, SameSeedSameFrameOtherSeedDiffers) {
  std::vector<Eigen::Vector3f> v;
  std::vector<std::uint32_t> t;
  add_tilted(75.0, 900.0f, v, t);
  add_rect(-100, -100, 100, 100, 700, v, t);
  KinectSensorModel model(registration, {});
  SensorFrame a, b, c;
  ASSERT_TRUE(model.capture(v, t, 11, a).ok());
  ASSERT_TRUE(model.capture(v, t, 11, b).ok());
  ASSERT_TRUE(model.capture(v, t, 12, c).ok());
  EXPECT_EQ(a.raw.pixels, b.raw.pixels);
  EXPECT_NE(a.raw.pixels, c.raw.pixels);
}

TEST_F(KinectSensorTest, GrazingSurfacesLoseDepth) {
  auto valid_fraction = [&](double deg) {
    KinectSensorOptions options;
    options.projector_shadow = false;
    std::vector<Eigen::Vector3f> v;
    std::vector<std::uint32_t> t;
    add_tilted(deg, 1000.0f, v, t);
    KinectSensorModel model(registration, options);
    SensorFrame frame;
    EXPECT_TRUE(model.capture(v, t, 5, frame).ok());
    // Central column only: there the view ray is along z, so the angle is `deg`.
    long valid = 0, covered = 0;
    for (int y = 200; y < 280; ++y) {
      for (int x = 318; x <= 322; ++x) {
        if (frame.noiseless_depth_mm.at(x, y) <= 0) continue;
        ++covered;
        valid += frame.depth_mm.at(x, y) != 0;
      }
    }
    EXPECT_GT(covered, 0);
    return static_cast<double>(valid) / std::max(covered, 1L);
  };
  EXPECT_EQ(valid_fraction(60.0), 1.0);
  EXPECT_EQ(valid_fraction(85.0), 0.0);
  const double middle = valid_fraction(77.0);
  EXPECT_GT(middle, 0.2);
  EXPECT_LT(middle, 0.8);
}

TEST_F(KinectSensorTest, ProjectorShadowBandOnTheLeftMatchesGeometry) {
  // A 200 mm box face at 800 mm in front of a wall at 1200 mm. The projector sits at +x, so the
  // wall strip just left of the box is lit by no ray: width f b (1/z_box - 1/z_wall) pixels.
  KinectSensorOptions options;
  options.dropouts = false;
  options.depth_noise = false;
  const float z_box = 800.0f, z_wall = 1200.0f;
  std::vector<Eigen::Vector3f> v;
  std::vector<std::uint32_t> t;
  add_rect(-3000, -3000, 3000, 3000, z_wall, v, t);
  add_rect(-100, -100, 100, 100, z_box, v, t);
  KinectSensorModel model(registration, options);
  SensorFrame frame;
  ASSERT_TRUE(model.capture(v, t, 1, frame).ok());
  const auto& k = model.intrinsics();
  const double expected = k.fx * model.projector_baseline_mm() * (1.0 / z_box - 1.0 / z_wall);
  const int y = static_cast<int>(k.cy);
  int box_left = -1, box_right = -1;
  for (int x = 0; x < k.width; ++x) {
    if (std::abs(frame.noiseless_depth_mm.at(x, y) - z_box) < 1.0f) {
      if (box_left < 0) box_left = x;
      box_right = x;
    }
  }
  ASSERT_GT(box_left, 0);
  int shadow_left = 0, shadow_right = 0, shadow_elsewhere = 0;
  for (int x = 0; x < k.width; ++x) {
    const bool shadow = frame.invalid.at(x, y) & kSensorProjectorShadow;
    if (!shadow) continue;
    if (x < box_left && x >= box_left - 40) {
      ++shadow_left;
    } else if (x > box_right && x <= box_right + 40) {
      ++shadow_right;
    } else {
      ++shadow_elsewhere;
    }
  }
  std::printf("shadow band: %d px measured, %.1f px expected\n", shadow_left, expected);
  EXPECT_NEAR(shadow_left, expected, 2.0);
  EXPECT_EQ(shadow_right, 0);
  EXPECT_EQ(shadow_elsewhere, 0);
  // The shadow band is contiguous and touches the box.
  for (int x = box_left - 1; x >= box_left - shadow_left; --x) {
    EXPECT_TRUE(frame.invalid.at(x, y) & kSensorProjectorShadow) << x;
  }
  // With the box removed there is no shadow at all.
  v.resize(4);
  t.resize(6);
  ASSERT_TRUE(model.capture(v, t, 1, frame).ok());
  for (auto bits : frame.invalid.pixels) ASSERT_EQ(bits & kSensorProjectorShadow, 0);
}

TEST_F(KinectSensorTest, SilhouettesLoseDepth) {
  KinectSensorOptions options;
  options.projector_shadow = false;
  std::vector<Eigen::Vector3f> v;
  std::vector<std::uint32_t> t;
  add_rect(-3000, -3000, 3000, 3000, 1200, v, t);
  add_rect(-100, -100, 100, 100, 800, v, t);
  KinectSensorModel model(registration, options);
  SensorFrame frame;
  ASSERT_TRUE(model.capture(v, t, 1, frame).ok());
  long edge = 0, edge_dropped = 0;
  for (std::size_t i = 0; i < frame.invalid.pixels.size(); ++i) {
    const int x = static_cast<int>(i % 640), y = static_cast<int>(i / 640);
    if (x == 0 || y == 0 || x == 639 || y == 479) continue;
    bool jump = false;
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dx = -1; dx <= 1; ++dx) {
        jump |= std::abs(frame.noiseless_depth_mm.at(x + dx, y + dy) -
                         frame.noiseless_depth_mm.at(x, y)) > 100;
      }
    }
    if (!jump) {
      ASSERT_EQ(frame.invalid.pixels[i] & kSensorDepthEdge, 0);
      continue;
    }
    ++edge;
    edge_dropped += (frame.invalid.pixels[i] & kSensorDepthEdge) != 0;
  }
  ASSERT_GT(edge, 400);
  EXPECT_NEAR(static_cast<double>(edge_dropped) / edge, options.edge_drop_probability, 0.1);
}

}  // namespace
}  // namespace fb
