// Landmarks: colour -> depth lifting against the synthetic camera's truth, and the dlib path
// (detection, tracking, no-face and bad-model errors, the packed 16-bit predictor against dlib's
// own) where Debian's model is installed.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>

#include <dlib/image_processing.h>

#include "algo/landmarks/landmark_detector.hpp"
#include "algo/landmarks/landmark_lifting.hpp"
#include "sim/camera/synthetic_camera.hpp"

namespace fb {
namespace {

constexpr const char* kPredictor = "/usr/share/dlib/shape_predictor_68_face_landmarks.dat";

// The model file's bytes, for tests that load several detectors from it.
std::string predictor_bytes() {
  std::ifstream in(kPredictor, std::ios::binary);
  std::stringstream model;
  model << in.rdbuf();
  return model.str();
}

struct Shot {
  RgbdFrame frame;
  FrameTruth truth;
  KinectCalibration calibration;
};

Shot shot(int frame_index = 0) {
  SyntheticOptions o;
  o.seed = 2;
  o.motion = SyntheticMotion::kStatic;
  o.sensor.depth_noise = false;
  o.frame_count = frame_index + 1;
  auto cam = make_synthetic_camera(o);
  EXPECT_TRUE(cam.ok());
  EXPECT_TRUE((*cam)->start().ok());
  Shot s;
  for (int i = 0; i <= frame_index; ++i)
    EXPECT_TRUE((*cam)->next_frame(s.frame, std::chrono::milliseconds(1000)).ok());
  s.truth = *frame_truth(**cam);
  s.calibration = (*cam)->info().calibration;
  return s;
}

TEST(Landmarks, LiftingPutsColourPointsOntoTheDepthImage) {
  const Shot s = shot();
  const KinectRegistration reg(s.calibration);
  auto lifted = lift_landmarks(s.truth.landmarks_color_px, depth_to_float(s.frame.depth_mm), reg);
  ASSERT_TRUE(lifted.ok()) << lifted.error().message;
  double px_err = 0, mm_err = 0;
  int n3 = 0;
  for (int l = 0; l < 68; ++l) {
    const FitLandmark& lm = (*lifted)[l];
    ASSERT_TRUE(lm.valid) << l;
    px_err += (lm.pixel - s.truth.landmarks_depth_px[l]).norm();
    if (is_contour_landmark(l)) {
      EXPECT_FALSE(lm.point.has_value());
    }
    if (!is_contour_landmark(l) && lm.point) {
      mm_err += (*lm.point - s.truth.landmarks_3d[l]).norm();
      ++n3;
    }
  }
  px_err /= 68;
  mm_err /= std::max(1, n3);
  std::printf("lifting: %.2f px mean, %.2f mm mean over %d interior 3D points\n", px_err, mm_err,
              n3);
  EXPECT_LT(px_err, 1.5);
  // Points whose 2x2 depth spans 3 mm or more (eye and lip rims, the brow ridge) stay 2D.
  EXPECT_GE(n3, 25);
  EXPECT_LT(mm_err, 3.0);
}

// color_to_depth_pixel's ring search with row pruning must pick the pixel a plain raster scan of
// the same window picks (nearest mapping, first in raster order on a tie). The scan is written
// out here as the reference, over colour points spread across the face and its silhouette.
TEST(Landmarks, LiftingSearchMatchesAPlainScan) {
  const Shot s = shot();
  const KinectRegistration reg(s.calibration);
  const Image<float> depth = depth_to_float(s.frame.depth_mm);
  const LiftOptions options;
  const double reference = 600.0;
  auto plain_scan = [&](const Eigen::Vector2d& target) -> std::optional<Eigen::Vector2d> {
    const int w = depth.width, h = depth.height;
    auto mapped = [&](int x, int y, Eigen::Vector2d& c) {
      std::uint16_t mm = static_cast<std::uint16_t>(reference);
      if (depth.contains(x, y)) {
        const float d = depth.at(x, y);
        if (d > 0.0f && std::abs(d - reference) <= options.depth_band_mm)
          mm = static_cast<std::uint16_t>(std::lround(d));
      }
      return reg.depth_to_color(x, y, mm, c.x(), c.y());
    };
    int gx = std::clamp(static_cast<int>(std::lround(target.x())), 0, w - 1);
    int gy = std::clamp(static_cast<int>(std::lround(target.y())), 0, h - 1);
    for (int pass = 0; pass < 2; ++pass) {
      Eigen::Vector2d c;
      if (!mapped(gx, gy, c)) break;
      gx = std::clamp(static_cast<int>(std::lround(gx + target.x() - c.x())), 0, w - 1);
      gy = std::clamp(static_cast<int>(std::lround(gy + target.y() - c.y())), 0, h - 1);
    }
    double best = 1e30;
    Eigen::Vector2d best_px = Eigen::Vector2d::Zero(), best_c = Eigen::Vector2d::Zero();
    const int r = options.search_radius_px;
    for (int y = gy - r; y <= gy + r; ++y)
      for (int x = gx - r; x <= gx + r; ++x) {
        Eigen::Vector2d c;
        if (x < 0 || y < 0 || x >= w || y >= h || !mapped(x, y, c)) continue;
        const double d = (c - target).squaredNorm();
        if (d < best) {
          best = d;
          best_px = {x, y};
          best_c = c;
        }
      }
    if (best > 4.0 * 4.0) return std::nullopt;
    return best_px + (target - best_c);
  };
  int compared = 0, found = 0;
  for (double y = 150.0; y < 360.0; y += 3.7)
    for (double x = 220.0; x < 430.0; x += 3.3) {
      const Eigen::Vector2d target(x + 0.25, y + 0.6);
      const auto ours = color_to_depth_pixel(target, depth, reg, reference, options);
      const auto theirs = plain_scan(target);
      ASSERT_EQ(ours.has_value(), theirs.has_value()) << x << " " << y;
      ++compared;
      if (!ours) continue;
      ++found;
      EXPECT_EQ(*ours, *theirs) << x << " " << y;
    }
  EXPECT_GT(found, compared / 2);
}

// The tracker maps its points straight from the raw 16-bit frame (landmark_depth_pixels); it
// must give the pixels lift_landmarks gives on the float copy, on a noisy frame with holes and
// with points off the face, and the same error where there is no depth.
TEST(Landmarks, PixelsFromTheRawFrameMatchTheLifting) {
  SyntheticOptions o;
  o.seed = 4;
  o.frame_count = 3;
  auto cam = make_synthetic_camera(o);
  ASSERT_TRUE(cam.ok());
  ASSERT_TRUE((*cam)->start().ok());
  RgbdFrame frame;
  for (int i = 0; i < 3; ++i)
    ASSERT_TRUE((*cam)->next_frame(frame, std::chrono::milliseconds(1000)).ok());
  const FrameTruth truth = *frame_truth(**cam);
  const KinectRegistration reg((*cam)->info().calibration);
  std::vector<Eigen::Vector2d> points(truth.landmarks_color_px.begin(),
                                      truth.landmarks_color_px.end());
  points[0] += Eigen::Vector2d(-60.0, 0.0);  // off the face, onto the background
  points[30] += Eigen::Vector2d(0.4, -0.3);
  auto lifted = lift_landmarks(points, depth_to_float(frame.depth_mm), reg);
  std::vector<float> box;
  auto raw = landmark_depth_pixels(points, frame.depth_mm, reg, {}, box);
  ASSERT_TRUE(lifted.ok()) << lifted.error().message;
  ASSERT_TRUE(raw.ok()) << raw.error().message;
  int valid = 0;
  for (int l = 0; l < 68; ++l) {
    const auto& px = (*raw)[static_cast<std::size_t>(l)];
    ASSERT_EQ(px.has_value(), (*lifted)[l].valid) << l;
    if (!px) continue;
    ++valid;
    EXPECT_EQ(*px, (*lifted)[l].pixel) << l;
  }
  EXPECT_GT(valid, 60);
  DepthImage empty;
  empty.resize(640, 480);
  auto none = landmark_depth_pixels(points, empty, reg, {}, box);
  ASSERT_FALSE(none.ok());
  EXPECT_NE(none.error().message.find("no depth"), std::string::npos);
}

TEST(Landmarks, LiftingWithoutDepthIsAnError) {
  const Shot s = shot();
  const KinectRegistration reg(s.calibration);
  Image<float> empty;
  empty.resize(640, 480);
  auto r = lift_landmarks(s.truth.landmarks_color_px, empty, reg);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("no depth"), std::string::npos);
}

TEST(Landmarks, DlibDetectsTracksAndReportsNoFace) {
  if (!std::filesystem::exists(kPredictor)) GTEST_SKIP() << "libdlib-data not installed";
  std::ifstream in(kPredictor, std::ios::binary);
  auto det = LandmarkDetector::create(in);
  ASSERT_TRUE(det.ok()) << det.error().message;
  const Shot s = shot();
  auto found = det->detect(s.frame.color);
  ASSERT_TRUE(found.ok()) << found.error().message;
  EXPECT_FALSE(found->tracked);
  double err = 0;
  for (int l = 0; l < 68; ++l) err += (found->points[l] - s.truth.landmarks_color_px[l]).norm();
  std::printf("dlib on the untextured render: %.2f px mean vs projected model landmarks\n",
              err / 68);
  EXPECT_LT(err / 68, 8.0);
  EXPECT_FALSE(found->from_landmarks);
  EXPECT_EQ(found->frames_since_detection, 0);
  auto again = det->detect(s.frame.color);
  ASSERT_TRUE(again.ok());
  EXPECT_TRUE(again->tracked);
  EXPECT_TRUE(again->from_landmarks);
  EXPECT_EQ(again->frames_since_detection, 1);
  EXPECT_EQ(again->detection_score, found->detection_score);  // the anchoring detection's
  // The face leaves: the points from the previous frame's box no longer sit on a face, the
  // detector re-runs and finds nothing.
  ColorImage blank;
  blank.resize(640, 480);
  auto none = det->detect(blank);
  ASSERT_FALSE(none.ok());
  EXPECT_NE(none.error().message.find("no face"), std::string::npos);
  auto back = det->detect(s.frame.color);  // lost: a full-image detection
  ASSERT_TRUE(back.ok());
  EXPECT_FALSE(back->tracked);
  std::istringstream garbage("not a model");
  EXPECT_FALSE(LandmarkDetector::create(garbage).ok());
}

// A still subject at `distance_mm` (seed 2): its colour image and true points.
std::pair<ColorImage, std::array<Eigen::Vector2d, 68>> still_at(double distance_mm) {
  SyntheticOptions o;
  o.seed = 2;
  o.motion = SyntheticMotion::kStatic;
  o.sensor.depth_noise = false;
  o.distance_mm = distance_mm;
  o.frame_count = 1;
  auto cam = make_synthetic_camera(o);
  EXPECT_TRUE(cam.ok());
  EXPECT_TRUE((*cam)->start().ok());
  RgbdFrame frame;
  EXPECT_TRUE((*cam)->next_frame(frame, std::chrono::milliseconds(1000)).ok());
  std::array<Eigen::Vector2d, 68> truth{};
  const FrameTruth t = *frame_truth(**cam);
  for (int l = 0; l < 68; ++l) truth[l] = t.landmarks_color_px[l];
  return {frame.color, truth};
}

// Re-anchoring: when the points tracked from the last frame are implausible (here the face
// jumped nearer), the detector searches a window around the last face resampled to a 96 px face
// over four pyramid levels. A face 1.2x and one 1.6x as near are both found there, with a box
// that grew with the face, and their points are as good as a first detection's.
// share(): a second detector on the same predictor gives the same points, and each keeps its
// own tracking state (the device's fit thread and tracking mode use one each).
TEST(Landmarks, SharedDetectorFindsTheSamePointsWithItsOwnTracking) {
  if (!std::filesystem::exists(kPredictor)) GTEST_SKIP() << "libdlib-data not installed";
  std::ifstream in(kPredictor, std::ios::binary);
  auto det = LandmarkDetector::create(in);
  ASSERT_TRUE(det.ok()) << det.error().message;
  LandmarkDetector shared = det->share();
  const Shot s = shot();
  auto first = det->detect(s.frame.color);
  ASSERT_TRUE(first.ok()) << first.error().message;
  auto second = det->detect(s.frame.color);
  ASSERT_TRUE(second.ok());
  EXPECT_TRUE(second->tracked);
  // The shared detector has seen no frame yet: a full-image detection, the same points.
  auto from_shared = shared.detect(s.frame.color);
  ASSERT_TRUE(from_shared.ok()) << from_shared.error().message;
  EXPECT_FALSE(from_shared->tracked);
  for (int l = 0; l < 68; ++l)
    EXPECT_LT((from_shared->points[l] - first->points[l]).norm(), 1e-9) << "point " << l;
}

TEST(Landmarks, DlibReanchorsOnTheResampledWindowWhenTheFaceJumpsNearer) {
  if (!std::filesystem::exists(kPredictor)) GTEST_SKIP() << "libdlib-data not installed";
  const std::string bytes = predictor_bytes();
  const auto far = still_at(800.0);
  // The detection on `far`, then on the subject at `distance_mm`.
  auto jump_to = [&](double distance_mm) -> std::pair<DetectedLandmarks, double> {
    std::istringstream in(bytes);
    auto det = LandmarkDetector::create(in);
    EXPECT_TRUE(det.ok());
    auto first = det->detect(far.first);
    EXPECT_TRUE(first.ok());
    EXPECT_FALSE(first->tracked);
    const auto target = still_at(distance_mm);
    auto second = det->detect(target.first);
    EXPECT_TRUE(second.ok());
    if (!first || !second) return {};
    double error = 0;
    for (int l = 0; l < 68; ++l) error += (second->points[l] - target.second[l]).norm();
    std::printf("800 -> %.0f mm: face box %d -> %d px, %s, %.2f px from the true points\n",
                distance_mm, first->face.width(), second->face.width(),
                second->tracked ? "window" : "full image", error / 68);
    EXPECT_FALSE(second->from_landmarks);
    return {*second, error / 68};
  };
  const auto [nearer, nearer_error] = jump_to(667.0);
  EXPECT_TRUE(nearer.tracked);
  EXPECT_GE(nearer.face.width(), 110);  // from 104 px
  EXPECT_LT(nearer_error, 3.5);
  const auto [near, near_error] = jump_to(500.0);
  EXPECT_TRUE(near.tracked);
  EXPECT_GE(near.face.width(), 130);
  EXPECT_LT(near_error, 3.5);
}

struct TakeFrame {
  ColorImage color;
  std::array<Eigen::Vector2d, 68> truth;  // projected model landmark vertices
};

std::vector<TakeFrame> head_turn_take(int frames) {
  SyntheticOptions o;
  o.seed = 2;
  o.motion = SyntheticMotion::kHeadTurn;  // yaw +-30 deg, pitch +-15 deg, 3 s period
  o.sensor.depth_noise = false;
  o.frame_count = frames;
  auto cam = make_synthetic_camera(o);
  EXPECT_TRUE(cam.ok());
  EXPECT_TRUE((*cam)->start().ok());
  std::vector<TakeFrame> out;
  RgbdFrame f;
  for (int i = 0; i < frames; ++i) {
    EXPECT_TRUE((*cam)->next_frame(f, std::chrono::milliseconds(1000)).ok());
    TakeFrame t;
    t.color = f.color;
    for (int l = 0; l < 68; ++l) t.truth[l] = frame_truth(**cam)->landmarks_color_px[l];
    out.push_back(std::move(t));
  }
  return out;
}

double mean_distance(const std::array<Eigen::Vector2d, 68>& a,
                     const std::array<Eigen::Vector2d, 68>& b) {
  double sum = 0;
  for (int l = 0; l < 68; ++l) sum += (a[l] - b[l]).norm();
  return sum / 68;
}

// Tracking from points over a head turn: the tracked frames' points stay close to a full
// detection on the same frame and as close to the true points as the windowed detector's
// (the previous tracking), the detector re-anchors every redetect_every frames, and the score is
// the anchoring detection's.
TEST(Landmarks, DlibTrackingFromPointsStaysCloseToFullDetections) {
  if (!std::filesystem::exists(kPredictor)) GTEST_SKIP() << "libdlib-data not installed";
  const std::string bytes = predictor_bytes();
  std::istringstream in1(bytes), in2(bytes), in3(bytes);
  LandmarkDetectorOptions full_options, window_options;
  full_options.track = false;
  window_options.track_landmarks = false;
  auto tracker = LandmarkDetector::create(in1);
  auto full = LandmarkDetector::create(in2, full_options);
  auto window = LandmarkDetector::create(in3, window_options);
  ASSERT_TRUE(tracker.ok() && full.ok() && window.ok());
  const int redetect_every = LandmarkDetectorOptions{}.redetect_every;
  const std::vector<TakeFrame> take = head_turn_take(45);  // half a period: 0 -> +30 deg -> 0
  const bool trace = std::getenv("FB_LANDMARK_TRACE") != nullptr;
  int from_points = 0, compared = 0, detections = 0;
  double vs_full = 0, worst = 0, anchor_score = 0, err_points = 0, err_window = 0, err_full = 0;
  for (std::size_t i = 0; i < take.size(); ++i) {
    const std::clock_t c0 = std::clock();
    auto t = tracker->detect(take[i].color);
    if (trace)
      std::printf("frame %zu: %s, %.2f ms CPU\n", i,
                  t ? (t->from_landmarks ? "points" : "detector") : "none",
                  1000.0 * double(std::clock() - c0) / CLOCKS_PER_SEC);
    auto f = full->detect(take[i].color);
    auto w = window->detect(take[i].color);
    if (!t) continue;
    if (!t->from_landmarks) {
      ++detections;
      anchor_score = t->detection_score;
      continue;
    }
    ++from_points;
    EXPECT_TRUE(t->tracked);
    EXPECT_LE(t->frames_since_detection, redetect_every) << i;
    EXPECT_EQ(t->detection_score, anchor_score) << i;
    if (!f || !w) continue;  // the frontal detector misses this view
    const double d = mean_distance(t->points, f->points);
    const double et = mean_distance(t->points, take[i].truth),
                 ew = mean_distance(w->points, take[i].truth),
                 ef = mean_distance(f->points, take[i].truth);
    if (trace)
      std::printf(
          "frame %zu: since %d, %.2f px from full; vs truth %.2f (window %.2f, full "
          "%.2f)\n",
          i, t->frames_since_detection, d, et, ew, ef);
    vs_full += d;
    worst = std::max(worst, d);
    err_points += et;
    err_window += ew;
    err_full += ef;
    ++compared;
  }
  ASSERT_GT(compared, 10);
  vs_full /= compared;
  err_points /= compared;
  err_window /= compared;
  err_full /= compared;
  std::printf(
      "tracking from points: %d of %zu frames (%d detector runs); on %d of them %.2f px "
      "mean from a full detection (worst frame %.2f px); vs the true points %.2f px "
      "(windowed detector %.2f, full image %.2f)\n",
      from_points, take.size(), detections, compared, vs_full, worst, err_points, err_window,
      err_full);
  EXPECT_GE(from_points, static_cast<int>(take.size()) / 2);
  EXPECT_LT(vs_full, 2.0);
  EXPECT_LT(worst, 6.0);
  EXPECT_LT(err_points, err_window + 0.5);
}

// The packed predictor (16-bit leaves, one scale per leaf vector) against dlib's own
// shape_predictor on the same grey image and face box, over a head turn: dlib's points are whole
// pixels, so the quantisation may only show as an occasional 1 px rounding step.
TEST(Landmarks, PackedPredictorMatchesDlibsShapePredictor) {
  if (!std::filesystem::exists(kPredictor)) GTEST_SKIP() << "libdlib-data not installed";
  const std::string bytes = predictor_bytes();
  std::istringstream ours_in(bytes), dlibs_in(bytes);
  LandmarkDetectorOptions full_only;
  full_only.track = false;
  auto ours = LandmarkDetector::create(ours_in, full_only);
  ASSERT_TRUE(ours.ok()) << ours.error().message;
  dlib::shape_predictor dlibs;
  dlib::deserialize(dlibs, dlibs_in);
  int compared = 0, differing = 0;
  double sum = 0, worst = 0;
  for (const TakeFrame& f : head_turn_take(30)) {
    auto found = ours->detect(f.color);
    if (!found) continue;
    dlib::array2d<unsigned char> gray(f.color.height, f.color.width);
    for (int y = 0; y < f.color.height; ++y)
      for (int x = 0; x < f.color.width; ++x) {
        const Rgb8& p = f.color.at(x, y);
        gray[y][x] = static_cast<unsigned char>((77 * p.r + 150 * p.g + 29 * p.b) >> 8);
      }
    const PixelRect& b = found->face;
    const dlib::full_object_detection theirs =
        dlibs(gray, dlib::rectangle(b.x0, b.y0, b.x1 - 1, b.y1 - 1));
    ASSERT_EQ(theirs.num_parts(), 68u);
    for (int l = 0; l < 68; ++l) {
      const double d =
          (found->points[l] - Eigen::Vector2d(theirs.part(l).x(), theirs.part(l).y())).norm();
      sum += d;
      worst = std::max(worst, d);
      differing += d > 0;
      ++compared;
    }
  }
  std::printf("packed vs dlib: %d points, %d differ, mean %.4f px, worst %.2f px\n", compared,
              differing, sum / std::max(compared, 1), worst);
  ASSERT_GE(compared, 68 * 20);
  EXPECT_LT(sum / compared, 0.05);
  EXPECT_LE(worst, 1.5);  // one rounding step, possibly in both coordinates
  EXPECT_LT(differing, compared / 20);
}

}  // namespace
}  // namespace fb
