// Registration check on the real dump: after KinectRegistration::register_depth_to_color, depth
// discontinuities must line up with edges of the colour image.
//
// Measure: colour edges = Canny(50, 150) of the blurred grey colour image. Depth edges =
// occlusion boundaries on their near side: a measured pixel whose first measured neighbour in
// some axis direction (skipping up to 8 unmeasured pixels: the IR shadow band and registration
// holes) is farther by more than max(100 mm, 8 %). For each depth-edge pixel (10 px image border
// excluded) take the distance to the nearest colour edge, clamped at 15 px (depth edges with no
// colour counterpart, e.g. a dark jacket fold, then cannot dominate). Per frame we report the
// median and the mean of these distances, and the global shift (dx, dy) in [-45, 45]^2 of the
// depth edges that minimises the mean. The unregistered depth image (IR pixels taken as colour
// pixels) is the baseline. Registered depth must beat it clearly, stay under a pixel threshold,
// and its best shift must be near (0, 0) while the baseline's is not.
#include <algorithm>
#include <cmath>
#include <iostream>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "drivers/camera/common/fakenect_dump.hpp"
#include "tests/camera_replay/test_dumps.hpp"

namespace fb {
namespace {

constexpr float kClamp = 15.0f;
constexpr int kBorder = 10;
constexpr int kMaxGap = 8;
constexpr int kMaxShift = 45;

cv::Mat colour_edge_distance(const ColorImage& color) {
  cv::Mat rgb(color.height, color.width, CV_8UC3, const_cast<Rgb8*>(color.pixels.data()));
  cv::Mat grey;
  cv::cvtColor(rgb, grey, cv::COLOR_RGB2GRAY);
  cv::GaussianBlur(grey, grey, cv::Size(5, 5), 1.2);
  cv::Mat edges;
  cv::Canny(grey, edges, 50, 150);
  cv::Mat non_edges = edges == 0;
  cv::Mat dist;
  cv::distanceTransform(non_edges, dist, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  return dist;
}

std::vector<cv::Point> depth_edges(const DepthImage& d) {
  std::vector<cv::Point> points;
  const int directions[4][2] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}};
  for (int y = kBorder; y < d.height - kBorder; ++y) {
    for (int x = kBorder; x < d.width - kBorder; ++x) {
      const int z = d.at(x, y);
      if (z == 0) continue;
      const int jump = std::max(100, z * 8 / 100);
      bool edge = false;
      for (const auto& o : directions) {
        for (int k = 1; k <= kMaxGap; ++k) {
          const int q = d.at(x + k * o[0], y + k * o[1]);
          if (q == 0) continue;
          edge = q - z > jump;
          break;
        }
        if (edge) break;
      }
      if (edge) points.emplace_back(x, y);
    }
  }
  return points;
}

struct Score {
  double mean = 0.0;
  double median = 0.0;
};

Score chamfer(const std::vector<cv::Point>& points, const cv::Mat& dist, int dx = 0, int dy = 0) {
  std::vector<float> d;
  d.reserve(points.size());
  for (const auto& p : points) {
    const int x = p.x + dx;
    const int y = p.y + dy;
    if (x < 0 || y < 0 || x >= dist.cols || y >= dist.rows) {
      d.push_back(kClamp);
    } else {
      d.push_back(std::min(dist.at<float>(y, x), kClamp));
    }
  }
  if (d.empty()) return {kClamp, kClamp};
  Score s;
  for (float v : d) s.mean += v;
  s.mean /= static_cast<double>(d.size());
  std::nth_element(d.begin(), d.begin() + d.size() / 2, d.end());
  s.median = d[d.size() / 2];
  return s;
}

struct Alignment {
  Score at_zero;
  int best_dx = 0;
  int best_dy = 0;
  double best_mean = 0.0;
};

Alignment align(const std::vector<cv::Point>& points, const cv::Mat& dist) {
  Alignment a;
  a.at_zero = chamfer(points, dist);
  a.best_mean = a.at_zero.mean;
  for (int dy = -kMaxShift; dy <= kMaxShift; ++dy) {
    for (int dx = -kMaxShift; dx <= kMaxShift; ++dx) {
      const double m = chamfer(points, dist, dx, dy).mean;
      if (m < a.best_mean) {
        a.best_mean = m;
        a.best_dx = dx;
        a.best_dy = dy;
      }
    }
  }
  return a;
}

TEST(RegistrationCheck, RegisteredDepthEdgesMatchColourEdges) {
  std::string why;
  const auto dir = test::real_dump_dir(why);
  if (dir.empty()) GTEST_SKIP() << why;
  auto reader = FakenectDumpReader::open(dir);
  ASSERT_TRUE(reader) << reader.error().message;
  ASSERT_TRUE(reader->device_calibration().has_value());
  const KinectRegistration reg(*reader->device_calibration());

  RgbdFrame frame;
  DepthImage registered;
  double reg_mean = 0, reg_median = 0, raw_mean = 0, raw_median = 0;
  double reg_dx = 0, reg_dy = 0, raw_dx = 0, raw_dy = 0;
  int frames = 0;
  for (int i = 0; i < 90; ++i) {
    auto got = reader->next(frame);
    ASSERT_TRUE(got && *got);
    if (i % 15 != 0) continue;  // frames 0, 15, ..., 75
    reg.disparity_to_mm(frame.raw_disparity, frame.depth_mm);
    reg.register_depth_to_color(frame.depth_mm, registered);
    const cv::Mat dist = colour_edge_distance(frame.color);
    const auto reg_edges = depth_edges(registered);
    const auto raw_edges = depth_edges(frame.depth_mm);
    ASSERT_GT(reg_edges.size(), 500u) << "frame " << i;
    ASSERT_GT(raw_edges.size(), 500u) << "frame " << i;
    const Alignment r = align(reg_edges, dist);
    const Alignment u = align(raw_edges, dist);
    std::cout << "[ registration ] frame " << i << ": registered mean " << r.at_zero.mean
              << " px median " << r.at_zero.median << " px best shift (" << r.best_dx << ", "
              << r.best_dy << ") -> " << r.best_mean << " | unregistered mean " << u.at_zero.mean
              << " px median " << u.at_zero.median << " px best shift (" << u.best_dx << ", "
              << u.best_dy << ") -> " << u.best_mean << " | edge pixels " << reg_edges.size() << "/"
              << raw_edges.size() << "\n";
    EXPECT_LT(r.at_zero.mean, u.at_zero.mean) << "frame " << i;
    reg_mean += r.at_zero.mean;
    reg_median += r.at_zero.median;
    raw_mean += u.at_zero.mean;
    raw_median += u.at_zero.median;
    reg_dx += r.best_dx;
    reg_dy += r.best_dy;
    raw_dx += u.best_dx;
    raw_dy += u.best_dy;
    ++frames;
  }
  const double n = frames;
  std::cout << "[ registration ] over " << frames << " frames: registered mean " << reg_mean / n
            << " px, median " << reg_median / n << " px, best shift (" << reg_dx / n << ", "
            << reg_dy / n << "); unregistered mean " << raw_mean / n << " px, median "
            << raw_median / n << " px, best shift (" << raw_dx / n << ", " << raw_dy / n << ")\n";
  RecordProperty("registered_mean_px", std::to_string(reg_mean / n));
  RecordProperty("registered_median_px", std::to_string(reg_median / n));
  RecordProperty("unregistered_mean_px", std::to_string(raw_mean / n));
  RecordProperty("unregistered_median_px", std::to_string(raw_median / n));
  // Registered depth edges sit on colour edges (median within 3 px, typical 2) and clearly better
  // than without registration.
  EXPECT_LT(reg_median / n, 3.0);
  EXPECT_LT(reg_median / n, 0.5 * (raw_median / n));
  EXPECT_LT(reg_mean / n, 0.75 * (raw_mean / n));
  // No residual global offset after registration, while the unregistered image is far off.
  EXPECT_LE(std::abs(reg_dx / n), 2.5);
  EXPECT_LE(std::abs(reg_dy / n), 2.5);
  EXPECT_GT(std::hypot(raw_dx / n, raw_dy / n), 10.0);
}

}  // namespace
}  // namespace fb
