#include "algo/tracking/depth_smoother.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>

#include <gtest/gtest.h>

namespace fb {
namespace {

// A plane at 700 mm (x < 40) and 720 mm (x >= 40) with 1 mm of noise (about the Kinect's
// 1.5 mm after the tracker's temporal mean), and one hole at (20, 30).
struct Scene {
  Image<float> truth, noisy;
};

Scene step_scene() {
  Scene s;
  s.truth.resize(80, 60);
  s.noisy.resize(80, 60);
  std::mt19937 rng(7);
  std::normal_distribution<float> noise(0.0f, 1.0f);
  for (int y = 0; y < 60; ++y) {
    for (int x = 0; x < 80; ++x) {
      s.truth.at(x, y) = x < 40 ? 700.0f : 720.0f;
      s.noisy.at(x, y) = s.truth.at(x, y) + noise(rng);
    }
  }
  s.noisy.at(20, 30) = 0.0f;
  return s;
}

double rms_error(const Image<float>& image, const Image<float>& truth, int x0, int x1) {
  double sum = 0.0;
  int n = 0;
  for (int y = 2; y < 58; ++y) {
    for (int x = x0; x < x1; ++x) {
      if (image.at(x, y) <= 0.0f) continue;
      sum += std::pow(image.at(x, y) - truth.at(x, y), 2);
      ++n;
    }
  }
  return std::sqrt(sum / n);
}

TEST(DepthFilter, EdgeAwareMeanLowersNoiseAndKeepsAStepSharp) {
  const Scene s = step_scene();
  Image<float> out = s.noisy;
  edge_aware_mean(s.noisy, {0, 0, 80, 60}, {.radius_px = 1, .range_mm = 3.0f}, out);

  // Smooth regions: 0.98 mm of noise drops to 0.37 (a plain 3x3 mean gives 1/3 of it; the
  // range test leaves out the few neighbours more than 3 mm from the centre).
  const double before = rms_error(s.noisy, s.truth, 2, 38);
  const double after = rms_error(out, s.truth, 2, 38);
  EXPECT_NEAR(before, 1.0, 0.1);
  EXPECT_LT(after, 0.42 * before) << before << " -> " << after;

  // The 20 mm step: the columns either side of it keep their own surface, 0.56 mm rms (a
  // plain mean would put them 6.7 mm off).
  const double at_step = std::max(rms_error(out, s.truth, 39, 40), rms_error(out, s.truth, 40, 41));
  EXPECT_LT(at_step, 0.8) << at_step;

  // The hole stays a hole and its neighbours do not read it as 0 mm.
  EXPECT_EQ(out.at(20, 30), 0.0f);
  EXPECT_NEAR(out.at(21, 30), 700.0f, 3.0f);
}

TEST(DepthFilter, WritesOnlyTheRectangleInterior) {
  const Scene s = step_scene();
  Image<float> out;
  out.resize(80, 60);  // zeros
  edge_aware_mean(s.noisy, {10, 10, 30, 20}, {.radius_px = 1, .range_mm = 3.0f}, out);
  int written = 0;
  for (int y = 0; y < 60; ++y)
    for (int x = 0; x < 80; ++x) written += out.at(x, y) != 0.0f ? 1 : 0;
  EXPECT_EQ(written, 18 * 8);
  EXPECT_EQ(out.at(10, 15), 0.0f);  // the border keeps whatever was there
  EXPECT_NE(out.at(11, 11), 0.0f);

  // Radius 0, or a rectangle too small for the window, writes nothing.
  Image<float> untouched;
  untouched.resize(80, 60);
  edge_aware_mean(s.noisy, {0, 0, 80, 60}, {.radius_px = 0, .range_mm = 3.0f}, untouched);
  edge_aware_mean(s.noisy, {5, 5, 7, 40}, {.radius_px = 1, .range_mm = 3.0f}, untouched);
  for (float d : untouched.pixels) ASSERT_EQ(d, 0.0f);
}

// The temporal mean over the ring: frames that agree with the newest are averaged, a frame
// that moved by more than temporal_range_mm does not count, out-of-range depth is invalid.
TEST(DepthSmoother, AveragesAgreeingFramesAndDoesNotSmearMotion) {
  DepthSmootherOptions options;
  options.spatial_radius_px = 0;  // the temporal mean alone
  DepthSmoother smoother;
  smoother.allocate(options, 40, 30);
  const PixelRect all{0, 0, 40, 30};
  std::mt19937 rng(3);
  std::normal_distribution<float> noise(0.0f, 1.5f);
  DepthImage frame;
  frame.resize(40, 30);
  auto fill = [&](float z) {
    for (auto& d : frame.pixels) d = static_cast<std::uint16_t>(std::lround(z + noise(rng)));
  };
  auto rms_about = [&](float z) {
    double sum = 0.0;
    for (float d : smoother.smoothed().pixels) sum += (d - z) * (d - z);
    return std::sqrt(sum / static_cast<double>(smoother.smoothed().pixels.size()));
  };
  int valid = 0;
  for (int f = 0; f < options.temporal_frames; ++f) {
    fill(700.0f);
    smoother.push(frame);
    valid = smoother.smooth(frame, all);
  }
  EXPECT_EQ(valid, 40 * 30);
  const double one_frame = std::sqrt(1.5 * 1.5 + 1.0 / 12.0);  // noise + rounding to 1 mm
  // 1.53 mm on one frame, 1.18 over five (seed 3): the range test down-weights older frames
  // that differ by a noise excursion, so the mean is weaker than sqrt(5), never a smear.
  const double averaged = rms_about(700.0f);
  EXPECT_LT(averaged, 0.85 * one_frame) << averaged;

  // The face moved 60 mm: the older frames disagree, the newest stands alone.
  fill(760.0f);
  smoother.push(frame);
  smoother.smooth(frame, all);
  for (std::size_t i = 0; i < frame.pixels.size(); ++i)
    ASSERT_EQ(smoother.smoothed().pixels[i], static_cast<float>(frame.pixels[i]));

  // Nearer than min_depth_mm: no valid pixel, all 0.
  std::fill(frame.pixels.begin(), frame.pixels.end(), std::uint16_t{300});
  smoother.push(frame);
  EXPECT_EQ(smoother.smooth(frame, all), 0);
  for (float d : smoother.smoothed().pixels) ASSERT_EQ(d, 0.0f);
}

}  // namespace
}  // namespace fb
