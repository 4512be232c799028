// Re-acquisition by detection (issue 6): the face is lost (all-invalid depth), moves 13 cm while
// lost, and comes back next to a nearer object (a flat box 25 cm in front of it, off to the
// side). The tracker's depth-only candidates fail there (the last pose sees background, the
// nearest-surface blob is the box); dlib on the colour image finds the face and its landmarks
// give ICP a start, so tracking resumes on the first frame back, at the true pose.
#include <fstream>
#include <numbers>

#include <gtest/gtest.h>

#include "algo/tracking/detected_landmarks.hpp"
#include "algo/tracking/face_tracker.hpp"
#include "sim/camera/synthetic_camera.hpp"
#include "storage/asset_files.hpp"

namespace fb {
namespace {

constexpr double kDeg = 180.0 / std::numbers::pi;
constexpr const char* kPredictor = "/usr/share/dlib/shape_predictor_68_face_landmarks.dat";

struct Frames {
  std::vector<RgbdFrame> frames;
  std::vector<FrameTruth> truth;
  CameraInfo info;
};

Frames render(const FaceModel& model, const SyntheticOptions& options) {
  Frames out;
  auto camera = make_synthetic_camera(model, options);
  EXPECT_TRUE(camera.ok()) << (camera.ok() ? "" : camera.error().message);
  if (!camera) return out;
  EXPECT_TRUE((*camera)->start().ok());
  out.info = (*camera)->info();
  RgbdFrame frame;
  while (true) {
    auto status = (*camera)->next_frame(frame, std::chrono::milliseconds(100));
    if (!status || *status != FrameStatus::kFrame) break;
    out.frames.push_back(frame);
    out.truth.push_back(*frame_truth(**camera));
  }
  return out;
}

// camera_from_model of a frontal face at (x, 0, 700) mm, yawed a little.
RigidPose frontal(double x_mm, double yaw_deg) {
  RigidPose p;
  const Eigen::Quaterniond flip(Eigen::AngleAxisd(std::numbers::pi, Eigen::Vector3d::UnitX()));
  p.rotation = flip * Eigen::AngleAxisd(yaw_deg / kDeg, Eigen::Vector3d::UnitY());
  p.translation = Eigen::Vector3d(x_mm, 0.0, 720.0);
  return p;
}

double rotation_error_deg(const RigidPose& a, const RigidPose& b) {
  return Eigen::AngleAxisd(a.rotation.conjugate() * b.rotation).angle() * kDeg;
}

struct Outcome {
  TrackState state_back = TrackState::kSearching;  // first frame with the face back
  RigidPose pose_back;
  bool detected_back = false;
};

Outcome run(const FaceModel& model, const Frames& take, TrackLandmarkSource* dlib) {
  Outcome outcome;
  auto tracker = FaceTracker::create(model, take.info.depth_intrinsics);
  EXPECT_TRUE(tracker.ok());
  if (!tracker) return outcome;
  EXPECT_TRUE((*tracker)->set_identity(take.truth[0].identity_coeffs).ok());
  TrackReport report;
  bool face_before = false;
  for (std::size_t f = 0; f < take.frames.size(); ++f) {
    RgbdFrame frame = take.frames[f];
    const bool lost = f >= 4 && f < 7;
    const bool back = f >= 7;
    if (lost) std::fill(frame.depth_mm.pixels.begin(), frame.depth_mm.pixels.end(), 0);
    if (back) {
      // The box: 140 x 260 px at 470 mm, on the left of the image (the face is on the right).
      for (int y = 110; y < 370; ++y)
        for (int x = 20; x < 160; ++x) frame.depth_mm.at(x, y) = 470;
    }
    const TrackLandmarks* landmarks = nullptr;
    bool detected = false;
    if (dlib != nullptr && !face_before) {
      detected = dlib->detect(frame.color, frame.depth_mm).found;
      landmarks = dlib->landmarks();
    }
    (*tracker)->track(frame.depth_mm, f / 30.0, landmarks, report);
    face_before = report.face_found;
    if (f < 4) {
      EXPECT_TRUE(report.face_found) << "frame " << f << ": " << report.loss_reason;
    }
    if (lost) {
      EXPECT_FALSE(report.face_found) << "frame " << f;
    }
    if (f == 7) {
      outcome.state_back = report.state;
      outcome.pose_back = report.raw_camera_from_model;
      outcome.detected_back = detected;
    }
  }
  return outcome;
}

TEST(Reacquire, DetectionFindsTheMovedFaceWhereDepthCandidatesFail) {
  auto model = load_face_model(std::filesystem::path(FB_DATA_DIR) / "facemodel.fbfm");
  ASSERT_TRUE(model.ok()) << model.error().message;
  std::ifstream in(kPredictor, std::ios::binary);
  if (!in) GTEST_SKIP() << kPredictor << " missing (Debian libdlib-data)";
  auto detector = LandmarkDetector::create(in);
  ASSERT_TRUE(detector.ok()) << detector.error().message;

  SyntheticOptions o;
  o.seed = 12;
  o.frame_count = 9;
  for (int f = 0; f < 9; ++f)
    o.camera_from_model_track.push_back(f < 5 ? frontal(-30.0, 5.0) : frontal(100.0, -8.0));
  const Frames take = render(*model, o);
  ASSERT_EQ(take.frames.size(), 9u);
  ASSERT_FALSE(take.frames[7].color.empty());

  TrackLandmarkSource dlib(std::move(*detector), take.info.calibration);
  const Outcome with = run(*model, take, &dlib);
  EXPECT_TRUE(with.detected_back);
  EXPECT_EQ(with.state_back, TrackState::kRecovered);
  EXPECT_LT(rotation_error_deg(with.pose_back, take.truth[7].camera_from_model), 1.0);
  const Eigen::Vector3d nose = take.truth[7].landmarks_3d[30];
  const Eigen::Vector3d nose_model = take.truth[7].camera_from_model.inverse().apply(nose);
  EXPECT_LT((with.pose_back.apply(nose_model) - nose).norm(), 2.0);

  // The same frames without detection: the depth candidates do not find the face there.
  const Outcome without = run(*model, take, nullptr);
  EXPECT_NE(without.state_back, TrackState::kRecovered);
}

}  // namespace
}  // namespace fb
