#include "algo/tracking/face_tracker.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <initializer_list>
#include <new>
#include <numbers>
#include <random>

#include <gtest/gtest.h>

#include "algo/tracking/arkit.hpp"
#include "algo/tracking/rig_view.hpp"
#include "sim/camera/synthetic_camera.hpp"
#include "storage/asset_files.hpp"
#include "tests/common/allocation_counter.hpp"
#include "tests/common/synthetic_take.hpp"
#include "tests/common/test_face_model.hpp"

namespace fb {
namespace {

constexpr double kDeg = 180.0 / std::numbers::pi;

using Frames = test::RenderedTake;
using test::render;

bool create_bad_model_ok() {
  FaceModel empty;
  return FaceTracker::create(empty, PinholeIntrinsics{640, 480, 580, 580, 320, 240}).ok();
}

double rotation_error_deg(const RigidPose& a, const RigidPose& b) {
  return Eigen::AngleAxisd(a.rotation.conjugate() * b.rotation).angle() * kDeg;
}

// The stand-in for the detector: the true 2D landmarks plus N(0, 1.5 px) noise per axis.
void noisy_landmarks(const FrameTruth& truth, std::mt19937& rng,
                     std::vector<Eigen::Vector2f>& points) {
  std::normal_distribution<float> noise(0.0f, 1.5f);
  points.resize(68);
  for (int l = 0; l < 68; ++l)
    points[l] = truth.landmarks_depth_px[l].cast<float>() + Eigen::Vector2f(noise(rng), noise(rng));
}

// Per-frame expression weights: all 0 until frame `start` (the calibration window), then each
// listed shape rises linearly to its peak over `rise` frames and stays there.
std::vector<std::vector<float>> ramp_track(int frames, int start, int rise,
                                           std::initializer_list<std::pair<int, float>> peaks) {
  std::vector<std::vector<float>> track(
      frames, std::vector<float>(test::face_model().expression_count, 0.0f));
  for (int f = start; f < frames; ++f) {
    const float s = std::min(1.0f, static_cast<float>(f - start) / static_cast<float>(rise));
    for (const auto& [shape, peak] : peaks) track[f][shape] = peak * s;
  }
  return track;
}

// Tracks `frames`, calibrating the identity, with truth + 1.5 px landmarks (noise seed
// `noise_seed`); on_frame(frame, truth, report, tracker) sees every frame.
template <class OnFrame>
void track_frames(const Frames& frames, const TrackerOptions& options, std::uint32_t noise_seed,
                  OnFrame on_frame) {
  auto tracker = FaceTracker::create(test::face_model(), frames.intrinsics, options);
  ASSERT_TRUE(tracker.ok()) << tracker.error().message;
  TrackReport report;
  std::mt19937 rng(noise_seed);
  std::vector<Eigen::Vector2f> points;
  for (std::size_t f = 0; f < frames.depth.size(); ++f) {
    noisy_landmarks(frames.truth[f], rng, points);
    TrackLandmarks landmarks{points, {}};
    (*tracker)->track(frames.depth[f], f / 30.0, &landmarks, report);
    on_frame(static_cast<int>(f), frames.truth[f], report, **tracker);
  }
}

// Renders `scene` and tracks it (track_frames()); on_frame(frame, truth, report) sees every
// frame reported as tracking.
template <class OnFrame>
void track_scene(const SyntheticOptions& scene, const TrackerOptions& options,
                 std::uint32_t noise_seed, OnFrame on_frame) {
  track_frames(render(scene), options, noise_seed,
               [&](int f, const FrameTruth& truth, const TrackReport& report, const FaceTracker&) {
                 if (report.state == TrackState::kTracking) on_frame(f, truth, report);
               });
}

TEST(ArkitMapping, FiftyTwoNamesAndTheModelShapes) {
  auto mapping = make_arkit_mapping(test::face_model());
  ASSERT_TRUE(mapping.ok()) << mapping.error().message;
  const auto index = [](std::string_view name) {
    return static_cast<int>(std::find(kArkitNames.begin(), kArkitNames.end(), name) -
                            kArkitNames.begin());
  };
  EXPECT_EQ(kArkitNames.front(), "eyeBlinkLeft");
  EXPECT_EQ(kArkitNames.back(), "tongueOut");
  const auto& s = mapping->sources;
  EXPECT_EQ(s[index("tongueOut")][0], -1);
  EXPECT_EQ(s[index("eyeBlinkLeft")][0], test::face_model().expression_index("eyeBlink_L"));
  EXPECT_EQ(s[index("jawOpen")][0], test::face_model().expression_index("jawOpen"));
  EXPECT_EQ(s[index("browInnerUp")][0], test::face_model().expression_index("browInnerUp_L"));
  EXPECT_EQ(s[index("browInnerUp")][1], test::face_model().expression_index("browInnerUp_R"));
  EXPECT_EQ(s[index("cheekPuff")][1], test::face_model().expression_index("cheekPuff_R"));
  // Every fitting shape is used exactly once.
  std::vector<int> used(test::face_model().fitting_expression_count, 0);
  for (const auto& pair : s)
    for (int j : pair)
      if (j >= 0) ++used[j];
  for (int j = 0; j < test::face_model().fitting_expression_count; ++j) EXPECT_EQ(used[j], 1) << j;
  // "_L" is the subject's left = model +X: eyeBlink_L moves vertices with x > 0.
  const auto shape =
      test::face_model().expression_shape(test::face_model().expression_index("eyeBlink_L"));
  double weighted_x = 0, total = 0;
  for (int v = 0; v < test::face_model().face_vertex_count; ++v) {
    const double d = Eigen::Vector3d(shape[3 * v], shape[3 * v + 1], shape[3 * v + 2]).norm();
    weighted_x += d * test::face_model().neutral[3 * v];
    total += d;
  }
  EXPECT_GT(weighted_x / total, 10.0);
  // Merged curves average their halves; to_model inverts.
  std::vector<float> w(test::face_model().fitting_expression_count, 0.0f);
  w[test::face_model().expression_index("browInnerUp_L")] = 0.2f;
  w[test::face_model().expression_index("browInnerUp_R")] = 0.6f;
  std::array<float, kArkitShapeCount> arkit{};
  mapping->to_arkit(w, arkit);
  EXPECT_NEAR(arkit[index("browInnerUp")], 0.4f, 1e-6f);
}

// A stored rig's shape names (model, ARKit or Live Link Face names) as the tracker's shapes.
TEST(ArkitMapping, StoredRigShapeNames) {
  const FaceModel& model = test::face_model();
  auto mapping = make_arkit_mapping(model);
  ASSERT_TRUE(mapping.ok()) << mapping.error().message;
  const int blink = model.expression_index("eyeBlink_L");
  ASSERT_GE(blink, 0);
  EXPECT_EQ(fitting_shape_for_name(model, *mapping, "eyeBlink_L"), blink);
  EXPECT_EQ(fitting_shape_for_name(model, *mapping, "eyeBlinkLeft"), blink);
  EXPECT_EQ(fitting_shape_for_name(model, *mapping, "EyeBlinkLeft"), blink);
  EXPECT_EQ(fitting_shape_for_name(model, *mapping, "browInnerUp"), -1);  // two model shapes
  EXPECT_EQ(fitting_shape_for_name(model, *mapping, "tongueOut"), -1);    // none
  EXPECT_EQ(fitting_shape_for_name(model, *mapping, "noSuchShape"), -1);
  for (int j = model.fitting_expression_count; j < model.expression_count; ++j)  // not fitted
    EXPECT_EQ(fitting_shape_for_name(model, *mapping, model.expression_names[j]), -1);
  const std::vector<float> neutral(model.neutral);
  const std::vector<std::string> names = {"JawOpen", "cheekPuff", "mouthSmile_R"};
  const std::vector<std::vector<float>> shapes(3, neutral);
  const TrackerRig view = tracker_rig_view(neutral, names, shapes, model, *mapping);
  ASSERT_EQ(view.shapes.size(), 2u);
  EXPECT_EQ(view.shapes[0].first, model.expression_index("jawOpen"));
  EXPECT_EQ(view.shapes[0].second.data(), shapes[0].data());
  EXPECT_EQ(view.shapes[1].first, model.expression_index("mouthSmile_R"));
  EXPECT_EQ(view.shapes[1].second.data(), shapes[2].data());
}

TEST(BoundedLsq, MatchesBruteForceOnABox) {
  std::mt19937 rng(2);
  std::normal_distribution<float> n(0.0f, 1.0f);
  for (int trial = 0; trial < 20; ++trial) {
    Eigen::Matrix<float, 6, 3> a;
    for (int i = 0; i < a.size(); ++i) a.data()[i] = n(rng);
    Eigen::Matrix<float, 6, 1> b;
    for (int i = 0; i < 6; ++i) b[i] = 1.5f * n(rng);
    ShapeMatrix h = a.transpose() * a;
    ShapeVector g = a.transpose() * b;
    ShapeVector w = ShapeVector::Zero(3);
    solve_bounded_lsq(h, g, 0.0f, 1.0f, w, 500, 1e-7f);
    auto cost = [&](const Eigen::Vector3f& x) { return (a * x - b).squaredNorm(); };
    float best = 1e30f;
    for (int i = 0; i <= 100; ++i)
      for (int j = 0; j <= 100; ++j)
        for (int k = 0; k <= 100; k += 1) {
          if ((i + j + k) % 3) continue;  // thin the grid
          best = std::min(best, cost(Eigen::Vector3f(i, j, k) / 100.0f));
        }
    EXPECT_LE(cost(w), best + 1e-3f);
    EXPECT_TRUE((w.array() >= 0.0f).all() && (w.array() <= 1.0f).all());
  }
}

// Known identity, static head, an expression, sensor noise, 2D landmarks (truth + 1.5 px
// noise, the stand-in for the detector): weights and pose against the ground truth.
TEST(Tracker, KnownIdentityExpressionWithNoise) {
  SyntheticOptions o;
  o.seed = 3;
  o.motion = SyntheticMotion::kStatic;
  o.frame_count = 12;
  o.expression_weights.assign(test::face_model().expression_count, 0.0f);
  o.expression_weights[test::face_model().expression_index("jawOpen")] = 0.5f;
  o.expression_weights[test::face_model().expression_index("mouthSmile_L")] = 0.6f;
  o.expression_weights[test::face_model().expression_index("browInnerUp_R")] = 0.4f;
  const Frames frames = render(o);
  ASSERT_EQ(frames.depth.size(), 12u);
  auto tracker = FaceTracker::create(test::face_model(), frames.intrinsics);
  ASSERT_TRUE(tracker.ok()) << tracker.error().message;
  ASSERT_TRUE((*tracker)->set_identity(frames.truth[0].identity_coeffs).ok());
  TrackReport report;
  std::mt19937 rng(1);
  std::vector<Eigen::Vector2f> points;
  for (std::size_t f = 0; f < frames.depth.size(); ++f) {
    noisy_landmarks(frames.truth[f], rng, points);
    TrackLandmarks landmarks{points, {}};
    (*tracker)->track(frames.depth[f], f / 30.0, &landmarks, report);
  }
  ASSERT_EQ(report.state, TrackState::kTracking);
  const auto& t = frames.truth.back();
  double mae = 0;
  for (int j = 0; j < report.shape_count; ++j)
    mae += std::abs(report.weights[j] - t.expression_weights[j]);
  mae /= report.shape_count;
  EXPECT_NEAR(report.weights[test::face_model().expression_index("jawOpen")], 0.5f, 0.1f);
  EXPECT_NEAR(report.weights[test::face_model().expression_index("mouthSmile_L")], 0.6f, 0.1f);
  // browInnerUp_R moves the brow along the forehead (tangential to the depth), a small depth
  // signal: a constant L1 prior held it at 0.06 for 0.4 (MAE 0.0075); scaled by the shape's
  // signal and relaxed on the shapes it turns on: 0.31 (MAE 0.0018).
  EXPECT_LT(mae, 0.004);
  EXPECT_NEAR(report.weights[test::face_model().expression_index("browInnerUp_R")], 0.4f, 0.15f);
  EXPECT_LT(rotation_error_deg(report.camera_from_model, t.camera_from_model), 0.5);
  const Eigen::Vector3d c = t.landmarks_3d[30];  // nose tip, camera frame
  const Eigen::Vector3d c_model = t.camera_from_model.inverse().apply(c);
  EXPECT_LT((report.camera_from_model.apply(c_model) - c).norm(), 1.0);
}

// The lids and a brow near the L1 onset, known identity, head turning, landmarks (truth +
// 1.5 px): the lid shapes have the least depth signal of the face (eyeWide 0.11 of the median
// shape's) and the gaze shapes move the same lid skin, so eyeWide must not be held at 0 as a
// weak shape nor come out as eyeLookUp, and a brow at 0.3 must not flicker off.
struct LidFrameErrors {
  float eye_wide_mean = 0;  // |eyeWide_R - 0.7|, mean over the frames
  float gaze_worst = 0;     // largest eyeLook* weight on any frame
  float brow_lowest = 1;    // lowest browDown_L (truth 0.3) on any frame
};

LidFrameErrors track_lids(const TrackerOptions& options) {
  SyntheticOptions o;
  o.seed = 17;
  o.frame_count = 30;
  o.expression_weights.assign(test::face_model().expression_count, 0.0f);
  o.expression_weights[test::face_model().expression_index("eyeWide_R")] = 0.7f;
  o.expression_weights[test::face_model().expression_index("browDown_L")] = 0.3f;
  o.expression_weights[test::face_model().expression_index("jawOpen")] = 0.3f;
  const Frames frames = render(o);
  LidFrameErrors e;
  EXPECT_EQ(frames.depth.size(), 30u);
  auto tracker = FaceTracker::create(test::face_model(), frames.intrinsics, options);
  EXPECT_TRUE(tracker.ok()) << tracker.error().message;
  if (!tracker || frames.depth.empty()) return e;
  EXPECT_TRUE((*tracker)->set_identity(frames.truth[0].identity_coeffs).ok());
  TrackReport report;
  std::mt19937 rng(7);
  std::vector<Eigen::Vector2f> points;
  for (std::size_t f = 0; f < frames.depth.size(); ++f) {
    noisy_landmarks(frames.truth[f], rng, points);
    TrackLandmarks landmarks{points, {}};
    (*tracker)->track(frames.depth[f], f / 30.0, &landmarks, report);
    EXPECT_EQ(report.state, TrackState::kTracking) << "frame " << f;
    if (f < 5) continue;  // the temporal term eases in from the neutral start
    e.eye_wide_mean +=
        std::abs(report.weights[test::face_model().expression_index("eyeWide_R")] - 0.7f) /
        static_cast<float>(frames.depth.size() - 5);
    e.brow_lowest =
        std::min(e.brow_lowest, report.weights[test::face_model().expression_index("browDown_L")]);
    for (int j = 0; j < report.shape_count; ++j)
      if (is_gaze_shape(test::face_model().expression_names[j]))
        e.gaze_worst = std::max(e.gaze_worst, report.weights[j]);
  }
  return e;
}

TEST(Tracker, LidsAreTrackedAndNotTakenByGaze) {
  const LidFrameErrors e = track_lids(TrackerOptions{});
  std::printf("eyeWide_R mean error %.3f, largest gaze weight %.3f, lowest browDown_L %.3f\n",
              e.eye_wide_mean, e.gaze_worst, e.brow_lowest);
  // Measured: 0.111, 0.016, 0.166. With the gaze shapes free and weak_shape_fraction 0.1:
  // 0.151, 0.244 (eyeLook* taking the lid), and without on_shape_sparsity the brow drops to 0
  // on some frames.
  EXPECT_LT(e.eye_wide_mean, 0.14f);
  EXPECT_LT(e.gaze_worst, 0.05f);
  EXPECT_GT(e.brow_lowest, 0.1f);
}

// A brow and a lid rise together (browDown_L 0 -> 0.6, eyeWide_R 0 -> 0.4; calibrated
// identity, head turning, landmarks truth + 1.5 px). Each has an antagonist on its side that
// partly cancels it (browInnerUp / browOuterUp raise the brow, eyeBlink / eyeSquint close the
// lid), and a pair switched on together can stand in for one of them. Of seeds 1-8, seed 6 is
// the one where that happens without the antagonist prior.
struct PairScene {
  double coactivation = 0;  // mean over frames of sum over pairs of min(w_a, w_b); truth 0
  double weight_mae = 0;    // over all shapes and the frames from the onset
};

PairScene track_rising_brow_and_lid(std::uint64_t seed, float antagonist_weight) {
  SyntheticOptions o;
  o.seed = seed;
  o.frame_count = 50;
  o.expression_track = ramp_track(o.frame_count, 14, 20,
                                  {{test::face_model().expression_index("browDown_L"), 0.6f},
                                   {test::face_model().expression_index("eyeWide_R"), 0.4f}});
  TrackerOptions options;
  options.weights.antagonist_weight = antagonist_weight;
  // The identity from depth alone: its misfit is what made the pair stand in here (the landmark
  // rows of the identity fit took it out of this scene, 0.0119 -> 0 co-activation).
  options.calibration.calibration_landmark_weight = 0.0f;
  const std::pair<const char*, const char*> pairs[] = {{"browDown_L", "browInnerUp_L"},
                                                       {"browDown_L", "browOuterUp_L"},
                                                       {"eyeWide_R", "eyeBlink_R"},
                                                       {"eyeWide_R", "eyeSquint_R"}};
  PairScene out;
  int n = 0;
  track_scene(o, options, static_cast<std::uint32_t>(seed),
              [&](int f, const FrameTruth& truth, const TrackReport& report) {
                if (f < 14) return;
                for (const auto& [a, b] : pairs)
                  out.coactivation +=
                      std::min(report.weights[test::face_model().expression_index(a)],
                               report.weights[test::face_model().expression_index(b)]);
                for (int j = 0; j < report.shape_count; ++j)
                  out.weight_mae += std::abs(report.weights[j] - truth.expression_weights[j]) /
                                    report.shape_count;
                ++n;
              });
  EXPECT_GT(n, 30) << "seed " << seed;
  out.coactivation /= std::max(n, 1);
  out.weight_mae /= std::max(n, 1);
  return out;
}

TEST(Tracker, AntagonistsDoNotStandInTogether) {
  const PairScene without = track_rising_brow_and_lid(6, 0.0f);
  const PairScene with = track_rising_brow_and_lid(6, TrackerOptions{}.weights.antagonist_weight);
  std::printf("co-activation %.4f -> %.4f, weight MAE %.4f -> %.4f\n", without.coactivation,
              with.coactivation, without.weight_mae, with.weight_mae);
  // Measured 0.0119 -> 0.0000, weight MAE 0.0048 -> 0.0046.
  EXPECT_GT(without.coactivation, 0.005);  // the scene shows the problem
  EXPECT_LT(with.coactivation, 0.002);
  EXPECT_LE(with.weight_mae, without.weight_mae + 1e-4);
}

// A stored subject rig (set_rig): the subject's neutral and personal shapes replace the model's
// identity face and deltas. The rendered face uses jawOpen at 0.5; the rig's jawOpen shape is
// the model's jawOpen delta doubled (a personal shape), so the rig tracker must report 0.25 for
// it, while a tracker with the model's deltas would report ~0.5.
TEST(Tracker, StoredRigReplacesIdentityAndShapes) {
  SyntheticOptions o;
  o.seed = 4;
  o.motion = SyntheticMotion::kStatic;
  o.frame_count = 10;
  o.expression_weights.assign(test::face_model().expression_count, 0.0f);
  const int jaw = test::face_model().expression_index("jawOpen");
  o.expression_weights[jaw] = 0.5f;
  const Frames frames = render(o);
  ASSERT_EQ(frames.depth.size(), 10u);
  const std::size_t size = 3 * static_cast<std::size_t>(test::face_model().vertex_count);
  std::vector<float> neutral(size);
  test::face_model().evaluate(frames.truth[0].identity_coeffs, {}, neutral);
  std::vector<float> jaw_shape(size);
  const auto delta = test::face_model().expression_shape(jaw);
  for (std::size_t i = 0; i < size; ++i) jaw_shape[i] = neutral[i] + 2.0f * delta[i];
  TrackerRig rig;
  rig.neutral = neutral;
  rig.shapes.emplace_back(jaw, jaw_shape);

  auto tracker = FaceTracker::create(test::face_model(), frames.intrinsics);
  ASSERT_TRUE(tracker.ok()) << tracker.error().message;
  ASSERT_TRUE((*tracker)->set_rig(rig).ok());
  EXPECT_TRUE((*tracker)->calibrated());
  TrackReport report;
  for (std::size_t f = 0; f < frames.depth.size(); ++f)
    (*tracker)->track(frames.depth[f], f / 30.0, nullptr, report);
  ASSERT_EQ(report.state, TrackState::kTracking);
  EXPECT_NEAR(report.weights[jaw], 0.25f, 0.06f);
  const auto& t = frames.truth.back();
  EXPECT_LT(rotation_error_deg(report.camera_from_model, t.camera_from_model), 0.5);
  const Eigen::Vector3d c = t.landmarks_3d[30];
  const Eigen::Vector3d c_model = t.camera_from_model.inverse().apply(c);
  EXPECT_LT((report.camera_from_model.apply(c_model) - c).norm(), 1.0);

  // Back to the model's deltas with the same identity: jawOpen reads 0.5 again.
  ASSERT_TRUE((*tracker)->set_identity(frames.truth[0].identity_coeffs).ok());
  for (std::size_t f = 0; f < frames.depth.size(); ++f)
    (*tracker)->track(frames.depth[f], 1.0 + f / 30.0, nullptr, report);
  EXPECT_NEAR(report.weights[jaw], 0.5f, 0.08f);

  // A rig in another topology is refused with an error.
  TrackerRig wrong;
  std::vector<float> small(30, 0.0f);
  wrong.neutral = small;
  EXPECT_FALSE((*tracker)->set_rig(wrong).ok());
}

// Unknown identity: calibration on the first frames, then a neutral face stays neutral, and
// head motion is followed (pose compared after the calibrated frame's constant offset).
TEST(Tracker, CalibratesAndFollowsAHeadTurn) {
  SyntheticOptions o;
  o.seed = 5;
  o.frame_count = 40;
  o.yaw_amplitude_deg = 15.0;
  o.pitch_amplitude_deg = 8.0;
  const Frames frames = render(o);
  ASSERT_EQ(frames.depth.size(), 40u);
  TrackerOptions options;
  auto tracker = FaceTracker::create(test::face_model(), frames.intrinsics, options);
  ASSERT_TRUE(tracker.ok()) << tracker.error().message;
  TrackReport report;
  std::vector<RigidPose> estimate, truth;
  std::vector<double> weight_mae;
  for (std::size_t f = 0; f < frames.depth.size(); ++f) {
    (*tracker)->track(frames.depth[f], f / 30.0, nullptr, report);
    if (!(*tracker)->calibrated() || report.state == TrackState::kCalibrating) continue;
    ASSERT_TRUE(report.face_found) << "frame " << f << ": " << report.loss_reason;
    estimate.push_back(report.camera_from_model);
    truth.push_back(frames.truth[f].camera_from_model);
    double mae = 0;
    for (int j = 0; j < report.shape_count; ++j) mae += report.weights[j];
    weight_mae.push_back(mae / report.shape_count);
  }
  ASSERT_GT(estimate.size(), 20u);
  EXPECT_TRUE((*tracker)->calibrated());
  // Relative motion from the first tracked frame: gauge-free.
  for (std::size_t i = 1; i < estimate.size(); ++i) {
    const Eigen::Quaterniond de = estimate[i].rotation * estimate[0].rotation.conjugate();
    const Eigen::Quaterniond dt = truth[i].rotation * truth[0].rotation.conjugate();
    EXPECT_LT(Eigen::AngleAxisd(de * dt.conjugate()).angle() * kDeg, 1.0) << "frame " << i;
  }
  double mean = 0;
  for (double e : weight_mae) mean += e;
  EXPECT_LT(mean / weight_mae.size(), 0.03);
}

// Paints a flat 90 x 110 mm plate (a palm) into a depth frame, `in_front_mm` nearer than the
// mouth, centred 25 mm above it (over mouth and nose) and `shift_mm` to the side: the plate's
// pixels take its depth, a 1-pixel rim around it mixes plate and face depth (flying pixels),
// and a band beside it is invalid (the Kinect projector's shadow).
struct PixelBox {
  int u0 = 0, v0 = 0, u1 = -1, v1 = -1;
  bool contains(const Eigen::Vector2d& p) const {
    return p.x() >= u0 && p.x() <= u1 && p.y() >= v0 && p.y() <= v1;
  }
};

// Returns the plate's pixels.
PixelBox paint_plate(DepthImage& depth, const FrameTruth& truth, const PinholeIntrinsics& k,
                     double shift_mm, double in_front_mm) {
  Eigen::Vector3d mouth = Eigen::Vector3d::Zero();
  for (int l = 48; l < 68; ++l) mouth += truth.landmarks_3d[l];
  mouth /= 20.0;
  const double z = mouth.z() - in_front_mm;
  const double x0 = mouth.x() + shift_mm - 45.0, x1 = x0 + 90.0;
  const double y0 = mouth.y() - 25.0 - 55.0, y1 = y0 + 110.0;
  auto px = [&](double x) { return k.fx * x / z + k.cx; };
  auto py = [&](double y) { return k.fy * y / z + k.cy; };
  const int u0 = static_cast<int>(std::floor(px(x0))), u1 = static_cast<int>(std::ceil(px(x1)));
  const int v0 = static_cast<int>(std::floor(py(y0))), v1 = static_cast<int>(std::ceil(py(y1)));
  constexpr int kShadowPx = 10;
  for (int v = v0 - 1; v <= v1 + 1; ++v) {
    for (int u = u0 - 1; u <= u1 + 1 + kShadowPx; ++u) {
      if (u < 0 || v < 0 || u >= depth.width || v >= depth.height) continue;
      auto& d = depth.pixels[static_cast<std::size_t>(v) * depth.width + u];
      const bool inside = u >= u0 && u <= u1 && v >= v0 && v <= v1;
      const bool rim = !inside && u <= u1 + 1;
      if (inside) {
        d = static_cast<std::uint16_t>(z);
      } else if (rim) {
        if (d > 0) d = static_cast<std::uint16_t>(0.5 * (d + z));
      } else if (v >= v0 && v <= v1) {
        d = 0;  // shadow
      }
    }
  }
  return {u0, v0, u1, v1};
}

// A plate passes in front of the lower face (calibrated identity, head turning, sensor noise;
// depth only, then with landmarks whose points under the plate are misdetected): the face is not
// lost, the shapes of the upper face (brows, lids), which the plate does not cover, stay at their
// truth, the pose is not dragged (gauge-free; most of the drift is the pose resting on the
// upper face alone), the covered mouth holds its expression, and tracking is back within 5
// frames after the plate has gone.
TEST(Tracker, OccluderDoesNotDragTheUpperFace) {
  SyntheticOptions o;
  o.seed = 11;
  o.frame_count = 46;
  o.yaw_amplitude_deg = 12.0;
  o.pitch_amplitude_deg = 6.0;
  // Neutral while the tracker calibrates the identity, then the mouth opens and smiles.
  o.expression_track = ramp_track(o.frame_count, 12, 10,
                                  {{test::face_model().expression_index("jawOpen"), 0.3f},
                                   {test::face_model().expression_index("mouthSmile_L"), 0.5f}});
  const Frames frames = render(o);
  ASSERT_EQ(frames.depth.size(), 46u);
  std::vector<int> upper;
  for (int j = 0; j < test::face_model().fitting_expression_count; ++j) {
    const std::string& name = test::face_model().expression_names[j];
    if (name.starts_with("brow") || name.starts_with("eyeWide") || name.starts_with("eyeSquint"))
      upper.push_back(j);
  }
  ASSERT_GE(upper.size(), 8u);
  std::vector<int> lower;  // the shapes under the plate: they hold their value
  for (int j = 0; j < test::face_model().fitting_expression_count; ++j) {
    const std::string& name = test::face_model().expression_names[j];
    if (name.starts_with("mouth") || name.starts_with("jaw")) lower.push_back(j);
  }
  double worst_lower = 0.0;  // of the last run
  // with_landmarks: truth + 1 px noise, and those under the plate misdetected 15 px down onto
  // it, as a detector's would be; the tracker must drop them itself.
  unsigned noise_seed = 5;  // of the landmark noise
  auto run = [&](const TrackerOptions& options, bool with_landmarks, double& worst_upper,
                 double& worst_rotation, int& recovery, int& misdetected_used) {
    auto tracker = FaceTracker::create(test::face_model(), frames.intrinsics, options);
    ASSERT_TRUE(tracker.ok()) << tracker.error().message;
    TrackReport report;
    worst_upper = worst_rotation = worst_lower = 0.0;
    recovery = -1;
    misdetected_used = 0;
    std::mt19937 rng(noise_seed);
    std::normal_distribution<float> noise(0.0f, 1.0f);
    std::vector<Eigen::Vector2f> points(68);
    constexpr int kFirst = 22, kLast = 37;  // plate in front of the face
    Eigen::Quaterniond reference = Eigen::Quaterniond::Identity();
    for (int f = 0; f < static_cast<int>(frames.depth.size()); ++f) {
      DepthImage depth = frames.depth[f];
      const FrameTruth& t = frames.truth[f];
      PixelBox plate;
      if (f >= kFirst && f <= kLast) {
        const double s = static_cast<double>(f - kFirst) / (kLast - kFirst);
        plate = paint_plate(depth, t, frames.intrinsics, -120.0 + 240.0 * s, 110.0);
      }
      int misdetected = 0;
      for (int l = 0; l < 68; ++l) {
        points[l] = t.landmarks_depth_px[l].cast<float>() + Eigen::Vector2f(noise(rng), noise(rng));
        if (plate.contains(t.landmarks_depth_px[l])) {
          points[l].y() += 15.0f;
          if (l >= 17) ++misdetected;
        }
      }
      TrackLandmarks landmarks{points, {}};
      (*tracker)->track(depth, f / 30.0, with_landmarks ? &landmarks : nullptr, report);
      // Every inner point the tracker uses beyond the free ones is a misdetected one.
      if (with_landmarks && report.landmarks_used > 51 - misdetected) ++misdetected_used;
      ASSERT_TRUE(report.face_found) << "frame " << f << ": " << report.loss_reason;
      double upper_error = 0.0, all_error = 0.0;
      for (int j : upper) upper_error += std::abs(report.weights[j] - t.expression_weights[j]);
      upper_error /= static_cast<double>(upper.size());
      double lower_error = 0.0;
      for (int j : lower) lower_error += std::abs(report.weights[j] - t.expression_weights[j]);
      lower_error /= static_cast<double>(lower.size());
      for (int j = 0; j < report.shape_count; ++j)
        all_error += std::abs(report.weights[j] - t.expression_weights[j]);
      all_error /= report.shape_count;
      // Gauge-free: the calibrated face's frame is off the true one by a constant rotation G
      // (R_est = R_true G), so the drag is the change of R_true^-1 R_est since before the plate.
      const Eigen::Quaterniond gauge =
          t.camera_from_model.rotation.conjugate() * report.camera_from_model.rotation;
      if (f == kFirst - 1) reference = gauge;
      const double rotation = Eigen::AngleAxisd(gauge * reference.conjugate()).angle() * kDeg;
      if (!(*tracker)->calibrated() || report.state == TrackState::kCalibrating) continue;
      if (f >= kFirst && f <= kLast) {
        worst_upper = std::max(worst_upper, upper_error);
        worst_lower = std::max(worst_lower, lower_error);
        worst_rotation = std::max(worst_rotation, rotation);
      } else if (f > kLast && recovery < 0 && all_error < 0.05 && rotation < 1.0) {
        recovery = f - kLast - 1;
      }
    }
  };
  double upper_error = 0, rotation = 0;
  int recovery = -1, misdetected_used = 0;
  run(TrackerOptions{}, false, upper_error, rotation, recovery, misdetected_used);
  std::fprintf(stderr, "depth only: upper %.4f, lower %.4f, rotation %.2f deg, recovery %d\n",
               upper_error, worst_lower, rotation, recovery);
  // The mouth and jaw shapes, constant while the plate covers them, hold their value: measured
  // 0.0025 (mean over those shapes, worst frame); without the imputed hidden rows 0.0231, the
  // few samples of the mouth's region still in view pulling them.
  EXPECT_LT(worst_lower, 0.008);
  {
    TrackerOptions no_hold;
    no_hold.weights.hidden_hold = 0.0f;
    double u = 0, r = 0;
    int rec = -1, mis = 0;
    run(no_hold, false, u, r, rec, mis);
    std::fprintf(stderr, "depth only, hidden_hold 0: lower %.4f\n", worst_lower);
    EXPECT_GT(worst_lower, 0.015);  // what the limit above guards against
  }
  // Measured 0.0000 and 0.61 deg.
  EXPECT_LT(upper_error, 0.004);
  EXPECT_LT(rotation, 1.2);
  EXPECT_GE(recovery, 0);
  EXPECT_LE(recovery, 5);

  // With landmarks, over 6 draws of their noise: a brow near its L1 onset turns on or not by
  // the draw (measured 0.0000 on 5 draws; 0.0150 on draw 5, browDown_L ~0.2 for a few frames
  // while the mouth opens, before the plate; the code before the calibrated depth offsets has
  // the same on draw 7 of 10), so the figure is the median draw, and no draw may go far.
  std::vector<double> upper_errors;
  for (noise_seed = 1; noise_seed <= 6; ++noise_seed) {
    run(TrackerOptions{}, true, upper_error, rotation, recovery, misdetected_used);
    std::fprintf(stderr,
                 "with landmarks (draw %u): upper %.4f, rotation %.2f deg, recovery %d, frames "
                 "using misdetected points %d\n",
                 noise_seed, upper_error, rotation, recovery, misdetected_used);
    upper_errors.push_back(upper_error);
    EXPECT_EQ(misdetected_used, 0);
    EXPECT_LT(rotation, 1.2);
    EXPECT_GE(recovery, 0);
    EXPECT_LE(recovery, 5);
  }
  std::sort(upper_errors.begin(), upper_errors.end());
  EXPECT_LT(upper_errors[upper_errors.size() / 2], 0.003);
  EXPECT_LT(upper_errors.back(), 0.02);
  TrackerOptions no_mask;
  no_mask.occlusion.occluder_margin_mm =
      0.0f;  // no occlusion test: the misdetected points are used
  // The plate's residuals raise the frame's noise estimate and with it the L1 weight, which
  // alone holds the upper face here (measured 0.0000); fixed priors show what the mask guards.
  no_mask.weights.prior_noise_reference_mm = 0.0f;
  noise_seed = 5;
  run(no_mask, true, upper_error, rotation, recovery, misdetected_used);
  std::fprintf(stderr,
               "with landmarks, no mask: upper %.4f, frames using misdetected points "
               "%d\n",
               upper_error, misdetected_used);
  EXPECT_GT(misdetected_used, 5);
  EXPECT_GT(upper_error, 0.02);  // measured 0.100: what the two limits above guard against
}

// A neutral face held while the head turns (random identities, calibrated, landmarks truth +
// 1.5 px): every weight should be 0. What the identity fit leaves of the face (modes it does not
// fit, the prior's shrinkage) otherwise shows up as weights; the per-sample depth offsets
// measured while calibrating take it out.
struct NeutralHold {
  double mean_weight = 0;  // over shapes and tracked frames
  double worst_weight = 0;
};

NeutralHold hold_neutral(std::uint64_t seed, bool depth_offsets) {
  SyntheticOptions o;
  o.seed = seed;
  o.frame_count = 40;
  o.expression_weights.assign(test::face_model().expression_count, 0.0f);
  TrackerOptions options;
  options.calibration.calibrate_depth_offsets = depth_offsets;
  // The identity from depth alone, whose misses the offsets are for (with the landmark rows in
  // the identity fit there is less to absorb: 0.00068 -> 0.00047).
  options.calibration.calibration_landmark_weight = 0.0f;
  NeutralHold out;
  int n = 0;
  track_scene(o, options, static_cast<std::uint32_t>(seed),
              [&](int, const FrameTruth&, const TrackReport& report) {
                for (int j = 0; j < report.shape_count; ++j) {
                  out.mean_weight += report.weights[j];
                  out.worst_weight = std::max<double>(out.worst_weight, report.weights[j]);
                }
                n += report.shape_count;
              });
  EXPECT_GT(n, 20 * test::face_model().fitting_expression_count) << "seed " << seed;
  out.mean_weight /= std::max(n, 1);
  return out;
}

TEST(Tracker, CalibratedDepthOffsetsAbsorbWhatTheIdentityFitMisses) {
  double with = 0, without = 0;
  for (std::uint64_t seed = 1; seed <= 4; ++seed) {
    const NeutralHold a = hold_neutral(seed, false), b = hold_neutral(seed, true);
    std::printf("seed %d: mean weight %.4f (largest %.3f) without offsets, %.4f (%.3f) with\n",
                static_cast<int>(seed), a.mean_weight, a.worst_weight, b.mean_weight,
                b.worst_weight);
    without += a.mean_weight / 4;
    with += b.mean_weight / 4;
  }
  // Measured: 0.00095 without, 0.00038 with (seed 1: 0.0018 -> 0.0003).
  EXPECT_LT(with, 0.6 * without) << without << " -> " << with;
  EXPECT_LT(with, 0.001);
}

// A detector that places this subject's brows 4 px low and the mouth corners 3 px out on every
// frame (dlib's point conventions differ from the model's landmark vertices, and the
// identity from depth is not exact at them): with the offsets measured while calibrating
// (neutral face) the bias does not reach the weights; without, it reads as expression on every
// frame.
TEST(Tracker, CalibratedLandmarkOffsetsAbsorbADetectorBias) {
  SyntheticOptions o;
  o.seed = 12;
  o.frame_count = 30;
  o.yaw_amplitude_deg = 8.0;
  o.pitch_amplitude_deg = 4.0;
  const int jaw = test::face_model().expression_index("jawOpen");
  o.expression_track.assign(o.frame_count,
                            std::vector<float>(test::face_model().expression_count, 0.0f));
  for (int f = 14; f < o.frame_count; ++f) o.expression_track[f][jaw] = 0.3f;
  const Frames frames = render(o);
  ASSERT_EQ(frames.depth.size(), 30u);
  auto run = [&](bool offsets, double& mae, double& brow_down) {
    TrackerOptions options;
    options.calibration.calibrate_landmark_offsets = offsets;
    auto tracker = FaceTracker::create(test::face_model(), frames.intrinsics, options);
    ASSERT_TRUE(tracker.ok()) << tracker.error().message;
    std::mt19937 rng(3);
    std::normal_distribution<float> noise(0.0f, 1.0f);
    std::vector<Eigen::Vector2f> points(68);
    TrackReport report;
    mae = brow_down = 0.0;
    int scored = 0;
    for (std::size_t f = 0; f < frames.depth.size(); ++f) {
      const FrameTruth& t = frames.truth[f];
      for (int l = 0; l < 68; ++l) {
        points[l] = t.landmarks_depth_px[l].cast<float>() + Eigen::Vector2f(noise(rng), noise(rng));
        if (l >= 17 && l <= 26) points[l].y() += 4.0f;  // brows
      }
      points[48].x() -= 3.0f;  // mouth corners (image x grows to the subject's left)
      points[54].x() += 3.0f;
      TrackLandmarks landmarks{points, {}};
      (*tracker)->track(frames.depth[f], f / 30.0, &landmarks, report);
      if (f < 16 || report.state != TrackState::kTracking) continue;
      double sum = 0.0;
      for (int j = 0; j < report.shape_count; ++j)
        sum += std::abs(report.weights[j] - t.expression_weights[j]);
      mae += sum / report.shape_count;
      brow_down += report.weights[test::face_model().expression_index("browDown_L")] +
                   report.weights[test::face_model().expression_index("browDown_R")];
      ++scored;
    }
    ASSERT_GE(scored, 10);
    mae /= scored;
    brow_down /= 2.0 * scored;
  };
  double mae_on = 0, brow_on = 0, mae_off = 0, brow_off = 0;
  run(true, mae_on, brow_on);
  run(false, mae_off, brow_off);
  std::fprintf(stderr, "offsets on: MAE %.4f, browDown %.3f; off: MAE %.4f, browDown %.3f\n",
               mae_on, brow_on, mae_off, brow_off);
  // Measured: MAE 0.0004 with offsets, 0.0111 without (browDown 0.000 and 0.228).
  EXPECT_LT(mae_on, 0.02);
  EXPECT_LT(brow_on, 0.04);
  EXPECT_GT(mae_off, 1.4 * mae_on);  // the bias is real: without the offsets it drags
}

// Bad input never crashes; it is reported.
TEST(Tracker, BadInputIsReported) {
  PinholeIntrinsics k{640, 480, 580.0, 580.0, 319.5, 239.5};
  auto tracker = FaceTracker::create(test::face_model(), k);
  ASSERT_TRUE(tracker.ok());
  TrackReport report;
  DepthImage wrong;
  wrong.resize(320, 240);
  (*tracker)->track(wrong, 0.0, nullptr, report);
  EXPECT_EQ(report.state, TrackState::kBadInput);
  EXPECT_FALSE(report.face_found);
  EXPECT_STRNE(report.loss_reason, "");
  DepthImage empty;
  empty.resize(640, 480);  // all invalid
  (*tracker)->track(empty, 0.033, nullptr, report);
  EXPECT_EQ(report.state, TrackState::kBadInput);
  EXPECT_FALSE(report.face_found);
  DepthImage wall;
  wall.resize(640, 480);
  std::fill(wall.pixels.begin(), wall.pixels.end(), std::uint16_t{1200});
  for (int i = 0; i < 5; ++i) {
    (*tracker)->track(wall, 0.066 + i / 30.0, nullptr, report);
    EXPECT_EQ(report.state, TrackState::kSearching);
    EXPECT_FALSE(report.face_found);
  }
  EXPECT_FALSE(create_bad_model_ok());
}

// Identity coefficients of an atypical face: one N(0, scale) draw per mode.
std::vector<float> atypical_identity(std::uint32_t seed, float scale) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> draw(0.0f, scale);
  std::vector<float> identity(static_cast<std::size_t>(test::face_model().identity_count));
  for (float& c : identity) c = draw(rng);
  return identity;
}

struct AcquisitionRun {
  int first_found = -1;            // first frame with a face
  int calibrated_at = -1;          // first frame calibrated
  double worst_tracked_deg = 0.0;  // largest rotation error of a frame reported as tracking
  std::string restart_reason;      // the loss reason when calibration started over
};

// Tracks a 20-frame head turn of `identity` with truth + 1.5 px landmarks from the first frame.
AcquisitionRun acquire_subject(std::uint32_t seed, const std::vector<float>& identity,
                               const TrackerOptions& options) {
  SyntheticOptions o;
  o.seed = seed;
  o.identity_coeffs = identity;
  o.frame_count = 20;
  o.yaw_amplitude_deg = 10.0;
  o.pitch_amplitude_deg = 5.0;
  AcquisitionRun run;
  track_frames(
      render(o), options, seed,
      [&](int f, const FrameTruth& truth, const TrackReport& report, const FaceTracker& tracker) {
        if (run.first_found < 0 && report.face_found) run.first_found = f;
        if (run.calibrated_at < 0 && tracker.calibrated()) run.calibrated_at = f;
        if (report.state == TrackState::kSearching && run.first_found >= 0 &&
            run.restart_reason.empty())
          run.restart_reason = report.loss_reason;
        if (report.state == TrackState::kTracking || report.state == TrackState::kRecovered) {
          run.worst_tracked_deg =
              std::max(run.worst_tracked_deg,
                       rotation_error_deg(report.camera_from_model, truth.camera_from_model));
        }
      });
  return run;
}

// Faces far from the mean (2 sigma in every identity mode) are fitted by the mean face only to
// 4-5 mm before calibration. With landmarks confirming the face, acquisition accepts that
// (uncalibrated_max_rms_mm) and calibration follows at once; with the tracking bound of 4 mm,
// two of these six subjects are never acquired in 20 frames.
TEST(Tracker, AcquiresAnAtypicalFaceWithLandmarks) {
  TrackerOptions strict;
  strict.loss.uncalibrated_max_rms_mm = strict.loss.max_rms_mm;
  int calibrated_by_10 = 0, calibrated = 0, strict_calibrated = 0;
  for (std::uint32_t seed = 1; seed <= 6; ++seed) {
    const std::vector<float> identity = atypical_identity(seed, 2.0f);
    const AcquisitionRun run = acquire_subject(seed, identity, TrackerOptions{});
    std::printf("seed %u: first face %d, calibrated %d, worst tracked %.2f deg\n", seed,
                run.first_found, run.calibrated_at, run.worst_tracked_deg);
    calibrated_by_10 += run.calibrated_at >= 0 && run.calibrated_at <= 10;
    calibrated += run.calibrated_at >= 0;
    if (run.calibrated_at >= 0) {
      EXPECT_LT(run.worst_tracked_deg, 10.0) << "seed " << seed;
    }
    strict_calibrated += acquire_subject(seed, identity, strict).calibrated_at >= 0;
  }
  // Measured: 5 of 6 by frame 10 (the sixth at frame 15), 6 of 6; with the strict bound 4.
  std::printf("calibrated by frame 10: %d, in 20 frames: %d; strict bound: %d\n", calibrated_by_10,
              calibrated, strict_calibrated);
  EXPECT_GE(calibrated_by_10, 5);
  EXPECT_EQ(calibrated, 6);
  EXPECT_LE(strict_calibrated, 4);
}

// Depth alone cannot tell a face fitted to 5 mm from a head-sized ellipsoid, so without
// landmarks the uncalibrated bound stays the tracking one: a ball 22 cm across and an egg
// 18 x 23 cm are not faces. With a 6 mm bound they are (the control).
TEST(Tracker, AHeadSizedEllipsoidIsNotAFace) {
  const PinholeIntrinsics k{640, 480, 580.0, 580.0, 319.5, 239.5};
  for (const auto& [radius, stretch] : {std::pair{110.0, 1.0}, std::pair{90.0, 1.3}}) {
    // Ray (x, y, 1) t against x^2 + (y / stretch)^2 + (z - cz)^2 = r^2, a wall behind.
    DepthImage depth;
    depth.resize(640, 480);
    const double cz = 700.0 + radius;
    for (int v = 0; v < 480; ++v) {
      for (int u = 0; u < 640; ++u) {
        const double x = (u - k.cx) / k.fx, y = (v - k.cy) / k.fy;
        const double a = x * x + y * y / (stretch * stretch) + 1.0;
        const double disc = cz * cz - a * (cz * cz - radius * radius);
        const double z = disc >= 0.0 ? (cz - std::sqrt(disc)) / a : 1200.0;
        depth.pixels[static_cast<std::size_t>(v) * 640 + u] = static_cast<std::uint16_t>(z);
      }
    }
    auto frames_found = [&](const TrackerOptions& options) {
      auto tracker = FaceTracker::create(test::face_model(), k, options);
      EXPECT_TRUE(tracker.ok());
      TrackReport report;
      int found = 0;
      for (int f = 0; f < 5; ++f) {
        (*tracker)->track(depth, f / 30.0, nullptr, report);
        found += report.face_found ? 1 : 0;
      }
      return found;
    };
    TrackerOptions loose;
    loose.loss.max_rms_mm = loose.loss.uncalibrated_max_rms_mm;
    EXPECT_EQ(frames_found(TrackerOptions{}), 0) << "radius " << radius << " x " << stretch;
    EXPECT_GT(frames_found(loose), 0) << "radius " << radius << " x " << stretch;
  }
}

// A subject so far from the mean face (2.5 sigma in every mode) that, with the identity fitted
// to depth alone, acquisition locks on at 24 deg and the pose walks to 38 deg while
// calibrating. The fitted face then explains its own calibration frames only to 3.0 mm RMS
// (right locks: 0.8-1.1 mm), above the 2 mm a re-acquisition must reach, so the tracker starts
// over instead of tracking the wrong pose; without that check (acquire_max_rms_mm 10) it
// reports tracking 38 deg off. (With the landmark rows in the identity fit this subject
// calibrates right, 0.7 deg; the check is the net under any identity fit that fails.)
TEST(Tracker, CalibrationThatDoesNotFitStartsOver) {
  const std::vector<float> identity = atypical_identity(5, 2.5f);
  TrackerOptions depth_only_fit;
  depth_only_fit.calibration.calibration_landmark_weight = 0.0f;
  const AcquisitionRun checked = acquire_subject(5, identity, depth_only_fit);
  TrackerOptions unchecked = depth_only_fit;
  unchecked.acquire.acquire_max_rms_mm = 10.0f;
  const AcquisitionRun trusted = acquire_subject(5, identity, unchecked);
  std::printf("checked: calibrated %d, worst tracked %.1f deg; unchecked: %d, %.1f deg\n",
              checked.calibrated_at, checked.worst_tracked_deg, trusted.calibrated_at,
              trusted.worst_tracked_deg);
  EXPECT_GT(trusted.worst_tracked_deg, 20.0);  // the scene shows the problem
  EXPECT_LT(checked.worst_tracked_deg, 5.0);
  // The user is told what happened and what to do.
  EXPECT_EQ(checked.restart_reason.rfind("calibration did not fit this face", 0), 0u)
      << checked.restart_reason;
  EXPECT_NE(checked.restart_reason.find("neutral face"), std::string::npos);
}

// The face disappears (all-invalid depth, then an empty room) and comes back: loss is
// reported once, the outputs hold, and tracking resumes.
TEST(Tracker, LossAndReacquisition) {
  SyntheticOptions o;
  o.seed = 6;
  o.motion = SyntheticMotion::kStatic;
  o.frame_count = 4;
  const Frames frames = render(o);
  auto tracker = FaceTracker::create(test::face_model(), frames.intrinsics);
  ASSERT_TRUE(tracker.ok());
  ASSERT_TRUE((*tracker)->set_identity(frames.truth[0].identity_coeffs).ok());
  TrackReport report;
  for (int f = 0; f < 3; ++f) (*tracker)->track(frames.depth[f], f / 30.0, nullptr, report);
  ASSERT_EQ(report.state, TrackState::kTracking);
  const RigidPose before = report.camera_from_model;
  DepthImage wall = frames.depth[0];
  std::fill(wall.pixels.begin(), wall.pixels.end(), std::uint16_t{1200});
  DepthImage nothing = frames.depth[0];
  std::fill(nothing.pixels.begin(), nothing.pixels.end(), std::uint16_t{0});
  (*tracker)->track(nothing, 0.1, nullptr, report);
  EXPECT_EQ(report.state, TrackState::kLost);
  EXPECT_FALSE(report.face_found);
  EXPECT_STRNE(report.loss_reason, "");
  EXPECT_LT(rotation_error_deg(report.camera_from_model, before), 1e-6);
  for (int f = 0; f < 3; ++f) {
    (*tracker)->track(wall, 0.13 + f / 30.0, nullptr, report);
    EXPECT_FALSE(report.face_found);
    EXPECT_NE(report.state, TrackState::kTracking);
  }
  (*tracker)->track(frames.depth[3], 0.3, nullptr, report);
  EXPECT_EQ(report.state, TrackState::kRecovered);
  EXPECT_TRUE(report.face_found);
  EXPECT_LT(rotation_error_deg(report.raw_camera_from_model, frames.truth[3].camera_from_model),
            0.5);
}

// Steady-state track() allocates nothing.
TEST(Tracker, SteadyStateDoesNotAllocate) {
  SyntheticOptions o;
  o.seed = 8;
  o.motion = SyntheticMotion::kStatic;
  o.frame_count = 8;
  const Frames frames = render(o);
  auto tracker = FaceTracker::create(test::face_model(), frames.intrinsics);
  ASSERT_TRUE(tracker.ok());
  ASSERT_TRUE((*tracker)->set_identity(frames.truth[0].identity_coeffs).ok());
  std::vector<Eigen::Vector2f> points(68);
  for (int l = 0; l < 68; ++l) points[l] = frames.truth[0].landmarks_depth_px[l].cast<float>();
  TrackLandmarks landmarks{points, {}};
  TrackReport report;
  for (int f = 0; f < 4; ++f) (*tracker)->track(frames.depth[f], f / 30.0, &landmarks, report);
  ASSERT_EQ(report.state, TrackState::kTracking);
  long allocations = 0;
  {
    test::CountAllocations counter;
    for (int f = 4; f < 8; ++f) (*tracker)->track(frames.depth[f], f / 30.0, &landmarks, report);
    allocations = counter.count();
  }
  if (test::allocation_counting_available()) {
    EXPECT_EQ(allocations, 0);
  }
  EXPECT_EQ(report.state, TrackState::kTracking);
  EXPECT_GT(report.landmarks_used, 40);
}

// Calibration fits the identity and the calibration frames' poses together: for these three
// random identities the mean face first meets the depth ~3 deg off (seed 37: upside down, righted
// while calibrating), and alternating identity solve and re-tracking stopped 3.0-4.9 deg off the
// true head frame (every later pose carried it); the joint fit ends within 0.55 deg (40 seeds: 0.44
// deg mean, 0.78 worst, none over 1; was 1.06 mean, 4.88 worst, 12 over 1). Depth only, raw
// (unfiltered) poses, the absolute frame.
TEST(Tracker, CalibrationFindsTheHeadFrameFromAFewDegreesOff) {
  for (const int seed : {4, 29, 37}) {
    SyntheticOptions o;
    o.seed = static_cast<std::uint64_t>(seed);
    o.frame_count = 24;
    o.yaw_amplitude_deg = 20.0;
    o.pitch_amplitude_deg = 10.0;
    const Frames frames = render(o);
    ASSERT_EQ(frames.depth.size(), 24u);
    auto tracker = FaceTracker::create(test::face_model(), frames.intrinsics, TrackerOptions{});
    ASSERT_TRUE(tracker.ok()) << tracker.error().message;
    TrackReport report;
    double sum = 0;
    int count = 0;
    for (std::size_t f = 0; f < frames.depth.size(); ++f) {
      (*tracker)->track(frames.depth[f], f / 30.0, nullptr, report);
      if (!(*tracker)->calibrated() || report.state == TrackState::kCalibrating) continue;
      ASSERT_TRUE(report.face_found) << "seed " << seed << " frame " << f;
      sum += rotation_error_deg(report.raw_camera_from_model, frames.truth[f].camera_from_model);
      ++count;
    }
    ASSERT_GE(count, 10) << "seed " << seed;
    EXPECT_LT(sum / count, 1.0) << "seed " << seed;
  }
}

// A landmark source that states its error (TrackLandmarks::noise_px) is weighed by it: with
// 6 px of noise per axis, 4x the 1.5 px the weights are set for, the stated noise counts the
// rows 1/16 as much and the weights follow the depth instead of the noise.
TEST(Tracker, NoisierLandmarkSourceCountsLess) {
  SyntheticOptions o;
  o.seed = 9;
  o.frame_count = 50;
  o.yaw_amplitude_deg = 15.0;
  o.pitch_amplitude_deg = 8.0;
  o.expression_track = ramp_track(50, 12, 15,
                                  {{test::face_model().expression_index("mouthSmile_L"), 0.6f},
                                   {test::face_model().expression_index("browInnerUp_R"), 0.5f},
                                   {test::face_model().expression_index("jawOpen"), 0.3f}});
  const Frames frames = render(o);
  auto weight_mae = [&](float stated_noise_px) {
    auto tracker = FaceTracker::create(test::face_model(), frames.intrinsics);
    EXPECT_TRUE(tracker.ok());
    if (!tracker) return 1.0;
    std::mt19937 rng(4);
    std::normal_distribution<float> noise(0.0f, 6.0f);
    std::vector<Eigen::Vector2f> points(68);
    TrackReport report;
    double sum = 0;
    int count = 0;
    for (std::size_t f = 0; f < frames.depth.size(); ++f) {
      for (int l = 0; l < 68; ++l)
        points[l] = frames.truth[f].landmarks_depth_px[l].cast<float>() +
                    Eigen::Vector2f(noise(rng), noise(rng));
      TrackLandmarks landmarks{points, {}, stated_noise_px};
      (*tracker)->track(frames.depth[f], f / 30.0, &landmarks, report);
      if (report.state != TrackState::kTracking) continue;
      for (int j = 0; j < report.shape_count; ++j)
        sum += std::abs(report.weights[j] - frames.truth[f].expression_weights[j]);
      count += report.shape_count;
    }
    EXPECT_GT(count, 30 * report.shape_count);
    return count ? sum / count : 1.0;
  };
  const double unstated = weight_mae(0.0f), stated = weight_mae(6.0f);
  std::printf("weight MAE with 6 px landmarks: noise unstated %.4f, stated %.4f\n", unstated,
              stated);
  EXPECT_LT(stated, 0.8 * unstated);
}

// TrackReport::weight_sigma is the data-only standard error of each weight: with the priors
// taken out, the solve's frame-to-frame error must match it. A static head with the true
// identity and a fixed expression, so the error is the sensor noise's alone; the brow's depth
// signal is a small fraction of the jaw's, and landmarks add to what the data says.
struct SigmaCheck {
  double mean = 0, rms = 0, sigma = 0;  // error of the solve: mean, spread; mean reported sigma
};

std::array<SigmaCheck, 2> weight_sigma_against_error(bool with_landmarks,
                                                     bool allocations_counted) {
  SyntheticOptions o;
  o.seed = 12;
  o.motion = SyntheticMotion::kStatic;
  o.frame_count = 60;
  const int jaw = test::face_model().expression_index("jawOpen");
  const int brow = test::face_model().expression_index("browDown_L");
  o.expression_weights.assign(test::face_model().expression_count, 0.0f);
  o.expression_weights[jaw] = 0.5f;
  o.expression_weights[brow] = 0.5f;
  o.expression_weights[test::face_model().expression_index("mouthSmile_R")] = 0.4f;
  const Frames frames = render(o);
  TrackerOptions options;
  options.weights.report_weight_sigma = true;
  // The plain least-squares solve the bound is for: no temporal, L1 or shape priors, and no
  // depth ring (each frame's noise its own).
  options.weights.temporal_weight = 0.0f;
  options.weights.sparsity = 0.0f;
  options.weights.ridge = 1e-3f;
  options.weights.weak_shape_ridge = 0.0f;
  options.weights.hold_gaze_shapes = false;
  options.weights.antagonist_weight = 0.0f;
  options.depth.temporal_frames = 1;
  std::array<SigmaCheck, 2> out{};
  auto tracker = FaceTracker::create(test::face_model(), frames.intrinsics, options);
  EXPECT_TRUE(tracker.ok());
  if (!tracker) return out;
  EXPECT_TRUE((*tracker)->set_identity(frames.truth[0].identity_coeffs).ok());
  TrackReport report;
  std::mt19937 rng(3);
  std::vector<Eigen::Vector2f> points;
  int n = 0;
  for (std::size_t f = 0; f < frames.depth.size(); ++f) {
    noisy_landmarks(frames.truth[f], rng, points);
    TrackLandmarks landmarks{points, {}};
    long allocations = 0;
    {
      test::CountAllocations counter;
      (*tracker)->track(frames.depth[f], f / 30.0, with_landmarks ? &landmarks : nullptr, report);
      allocations = counter.count();
    }
    if (allocations_counted && f >= 5 && test::allocation_counting_available()) {
      EXPECT_EQ(allocations, 0) << "frame " << f;
    }
    EXPECT_EQ(report.state, TrackState::kTracking);
    if (f < 5) continue;
    ++n;
    for (int s = 0; s < 2; ++s) {
      const int j = s == 0 ? jaw : brow;
      const double e = report.weights[j] - 0.5;
      out[s].rms += e * e;
      out[s].mean += e;
      out[s].sigma += report.weight_sigma[j];
    }
  }
  for (auto& c : out) {
    c.mean /= std::max(n, 1);
    c.rms = std::sqrt(std::max(0.0, c.rms / std::max(n, 1) - c.mean * c.mean));
    c.sigma /= std::max(n, 1);
  }
  return out;
}

// Measured (seed 12, 55 frames): depth only, jawOpen error sd 0.027 against sigma 0.021,
// browDown_L 0.103 against 0.118; with landmarks 0.008 against 0.021 (the bounded solve clips
// the mouth shapes that share the jaw's signal, so it scatters less than the unbounded bound)
// and 0.108 against 0.099. The priors the test takes out are what bring the brow's error down
// in tracking (WeightSolverOptions::temporal_weight and sparsity).
TEST(Tracker, WeightSigmaIsTheDataOnlyStandardError) {
  const auto depth_only = weight_sigma_against_error(false, true);
  const auto with_landmarks = weight_sigma_against_error(true, false);
  for (const auto* c : {&depth_only, &with_landmarks}) {
    SCOPED_TRACE(c == &depth_only ? "depth only" : "with landmarks");
    const SigmaCheck& jaw = (*c)[0];
    const SigmaCheck& brow = (*c)[1];
    EXPECT_GT(brow.sigma, 3.0 * jaw.sigma);
    EXPECT_GT(brow.rms, 0.7 * brow.sigma);
    EXPECT_LT(brow.rms, 1.35 * brow.sigma);
    EXPECT_LT(jaw.rms, 1.5 * jaw.sigma);
  }
  EXPECT_LT(with_landmarks[1].sigma, 0.95 * depth_only[1].sigma);
}

}  // namespace
}  // namespace fb
