// ViewConsistency against frames with known noise: a plane seen by a camera moving towards it
// (the fused surface: the plane itself), with one patch that scatters and drops out the way
// hair does on a Kinect v1.
#include <gtest/gtest.h>

#include <random>

#include "algo/fusion/view_consistency.hpp"

namespace fb {
namespace {

PinholeIntrinsics camera() {
  PinholeIntrinsics k;
  k.fx = k.fy = 580.0;
  k.cx = 320.0;
  k.cy = 240.0;
  return k;
}

bool in_patch(int x, int y) {
  return x >= 300 && x < 340 && y >= 200 && y < 240;
}

// Frame i: the camera 2 i mm nearer the plane z = 700 mm (reference frame), skin noise 0.6 mm,
// the patch 5 mm and 30 % dropouts.
DepthImage frame(int i, std::mt19937& rng) {
  std::normal_distribution<double> skin(0.0, 0.6), hair(0.0, 5.0);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  DepthImage d;
  d.resize(640, 480);
  for (int y = 0; y < 480; ++y)
    for (int x = 0; x < 640; ++x) {
      const bool patch = in_patch(x, y);
      if (x < 200 || x >= 440 || y < 120 || y >= 360 || (patch && u(rng) < 0.3)) {
        d.at(x, y) = 0;
        continue;
      }
      const double z = 700.0 - 2.0 * i + (patch ? hair(rng) : skin(rng));
      d.at(x, y) = static_cast<std::uint16_t>(std::lround(z));
    }
  return d;
}

// The fused surface seen from frame i, at half resolution as fusion's model view is.
Image<float> model_view(int i) {
  Image<float> m;
  m.resize(320, 240);
  for (int y = 0; y < 240; ++y)
    for (int x = 0; x < 320; ++x)
      m.at(x, y) = x >= 100 && x < 220 && y >= 60 && y < 180 ? 700.0f - 2.0f * i : 0.0f;
  return m;
}

TEST(ViewConsistency, ScatterAndDropoutsReadLowAndAgreeingSkinHigh) {
  ViewConsistency vc;
  ASSERT_TRUE(vc.reset(camera()).ok());
  std::mt19937 rng(7);
  for (int i = 0; i < 20; ++i) {
    RigidPose reference_from_camera;
    reference_from_camera.translation = Eigen::Vector3d(0, 0, 2.0 * i);
    vc.add(frame(i, rng), model_view(i), reference_from_camera, PixelRect{});
  }
  EXPECT_EQ(vc.frames(), 20);
  Image<float> c;
  vc.confidence(c);
  double skin = 0, hair = 0;
  int n_skin = 0, n_hair = 0;
  for (int y = 150; y < 330; ++y)
    for (int x = 230; x < 410; ++x) {
      if (in_patch(x, y)) {
        hair += c.at(x, y);
        ++n_hair;
      } else if (x < 295 || x >= 345 || y < 195 || y >= 245) {
        skin += c.at(x, y);
        ++n_skin;
      }
    }
  skin /= n_skin;
  hair /= n_hair;
  std::printf("confidence: skin %.3f, hair-like patch %.3f\n", skin, hair);
  EXPECT_GT(skin, 0.8);
  EXPECT_LT(hair, 0.3);
  EXPECT_EQ(c.at(10, 10), 0.0f);  // never observed
}

TEST(ViewConsistency, AFrameOffTheFusedSurfaceDisagrees) {
  // Frames 2 mm a step off the surface they are compared with (a pose fusion got wrong): the
  // residuals grow over the take and read as scatter against the first half of the frames.
  ViewConsistency vc;
  ASSERT_TRUE(vc.reset(camera()).ok());
  std::mt19937 rng(7);
  for (int i = 0; i < 20; ++i) {
    RigidPose reference_from_camera;
    reference_from_camera.translation = Eigen::Vector3d(0, 0, 2.0 * i);
    // Half the frames compared with the surface where it is, half 4-8 mm off.
    vc.add(frame(i, rng), model_view(i < 10 ? i : i + 2 + (i % 3)), reference_from_camera,
           PixelRect{});
  }
  Image<float> c;
  vc.confidence(c);
  // Every pixel disagrees alike, so relative to the typical scatter it is not singled out...
  EXPECT_GT(c.at(250, 300), 0.9);
  // ...but the hair-like patch still scatters more than that.
  EXPECT_LT(c.at(320, 220), 0.6);
}

TEST(ViewConsistency, BadSetupIsAClearError) {
  ViewConsistency vc;
  PinholeIntrinsics k = camera();
  k.fx = 0;
  auto r = vc.reset(k);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("intrinsics"), std::string::npos);
}

}  // namespace
}  // namespace fb
