// Landmarks: colour -> depth lifting against the synthetic camera's truth, and the dlib path
// (detection, tracking, no-face and bad-model errors) where Debian's model is installed.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "algo/landmarks/landmark_detector.hpp"
#include "algo/landmarks/landmark_lifting.hpp"
#include "drivers/camera/synthetic/synthetic_camera.hpp"

namespace fb {
namespace {

constexpr const char* kPredictor = "/usr/share/dlib/shape_predictor_68_face_landmarks.dat";

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
  s.truth = *(*cam)->truth();
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
    } else if (lm.point) {
      mm_err += (*lm.point - s.truth.landmarks_3d[l]).norm();
      ++n3;
    }
  }
  px_err /= 68;
  mm_err /= std::max(1, n3);
  std::printf("lifting: %.2f px mean, %.2f mm mean over %d interior 3D points\n", px_err, mm_err,
              n3);
  EXPECT_LT(px_err, 1.5);
  EXPECT_GT(n3, 30);
  EXPECT_LT(mm_err, 3.0);
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
  auto again = det->detect(s.frame.color);
  ASSERT_TRUE(again.ok());
  EXPECT_TRUE(again->tracked);
  ColorImage blank;
  blank.resize(640, 480);
  auto none = det->detect(blank);
  ASSERT_FALSE(none.ok());
  EXPECT_NE(none.error().message.find("no face"), std::string::npos);
  std::istringstream garbage("not a model");
  EXPECT_FALSE(LandmarkDetector::create(garbage).ok());
}

}  // namespace
}  // namespace fb
