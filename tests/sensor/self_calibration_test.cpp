// Self-calibration: the registration of a decalibrated unit recovered from ordinary frames
// (synthetic head turns with known truth), and on the real openiss dump: its own device.json
// must read as healthy, and a deliberately wrong start must be corrected back to it.
#include <chrono>
#include <cmath>
#include <iostream>

#include <gtest/gtest.h>

#include "algo/sensor/self_calibration.hpp"
#include "drivers/camera/common/calibrated_camera.hpp"
#include "drivers/camera/common/device_json.hpp"
#include "drivers/camera/common/fakenect_dump.hpp"
#include "sim/camera/synthetic_camera.hpp"
#include "storage/asset_files.hpp"
#include "tests/camera_replay/test_dumps.hpp"

namespace fb {
namespace {

struct UnitRun {
  SelfCalibrationResult result;
  RegistrationCorrection truth;
};

UnitRun run_synthetic(const std::string& arguments, int frames) {
  auto model = load_face_model();
  EXPECT_TRUE(model) << model.error().message;
  auto options = parse_synthetic_options(arguments, *model);
  EXPECT_TRUE(options) << options.error().message;
  auto camera = make_synthetic_camera(*model, *options);
  EXPECT_TRUE(camera) << camera.error().message;
  EXPECT_TRUE((*camera)->start());
  SelfCalibrator calibrator((*camera)->info().calibration);
  RgbdFrame frame;
  for (int i = 0; i < frames; ++i) {
    auto got = (*camera)->next_frame(frame, std::chrono::milliseconds(100));
    EXPECT_TRUE(got && *got == FrameStatus::kFrame);
    calibrator.add_frame(frame.depth_mm, frame.color);
  }
  auto r = calibrator.estimate();
  EXPECT_TRUE(r) << r.error().message;
  return {*r, options->calibration.correction};
}

TEST(SelfCalibration, RecoversADecalibratedUnit) {
  const UnitRun run = run_synthetic("seed=3,frames=30,reg_dx=11,reg_dy=-14,reg_rot=0.6", 30);
  const auto& c = run.result.correction;
  const double error = registration_distance_px(c, run.truth);
  std::cout << "[ self-cal ] estimate (" << c.dx_px << ", " << c.dy_px << ", " << c.rotation_deg
            << " deg) truth (11, -14, 0.6): error " << error << " px, residual "
            << run.result.residual_px << " px, misregistration " << run.result.misregistration_px
            << " px, confidence " << run.result.confidence << "\n";
  EXPECT_TRUE(run.result.ok) << run.result.why;
  EXPECT_LT(error, 1.0);
  // The defaults it started from are off by the unit's offset, about 18 px.
  EXPECT_NEAR(run.result.misregistration_px, registration_distance_px({}, run.truth), 1.0);
  EXPECT_LT(run.result.residual_px, 1.0);
}

TEST(SelfCalibration, ACalibratedUnitReadsHealthy) {
  const UnitRun run = run_synthetic("seed=5,frames=20,unit=7,calibrated=1", 20);
  EXPECT_TRUE(run.result.ok) << run.result.why;
  EXPECT_LT(run.result.misregistration_px, 1.0);
}

TEST(SelfCalibration, NoDepthEdgesIsNotOk) {
  // The face alone before an empty background: no measured far side, no edge samples.
  const UnitRun run = run_synthetic("seed=1,frames=5,motion=static,background=off", 5);
  EXPECT_FALSE(run.result.ok);
  EXPECT_NE(run.result.why.find("depth-edge samples"), std::string::npos) << run.result.why;
}

TEST(SelfCalibration, RealDumpIsHealthyAndAWrongStartIsCorrected) {
  std::string why;
  const auto dir = test::real_dump_dir(why);
  if (dir.empty()) GTEST_SKIP() << why;
  auto reader = FakenectDumpReader::open(dir);
  ASSERT_TRUE(reader) << reader.error().message;
  ASSERT_TRUE(reader->device_calibration().has_value());
  const KinectCalibration device = *reader->device_calibration();
  KinectCalibration wrong = device;
  wrong.correction.dx_px = 6.0;
  wrong.correction.dy_px = -13.0;
  SelfCalibrator from_device(device);
  SelfCalibrator from_wrong(wrong);
  const KinectRegistration reg(device);
  RgbdFrame frame;
  for (int i = 0; i < 90; ++i) {
    auto got = reader->next(frame);
    ASSERT_TRUE(got && *got);
    reg.disparity_to_mm(frame.raw_disparity, frame.depth_mm);
    from_device.add_frame(frame.depth_mm, frame.color);
    from_wrong.add_frame(frame.depth_mm, frame.color);
  }
  auto a = from_device.estimate();
  auto b = from_wrong.estimate();
  ASSERT_TRUE(a && b);
  std::cout << "[ self-cal ] openiss from its device.json: (" << a->correction.dx_px << ", "
            << a->correction.dy_px << ", " << a->correction.rotation_deg << " deg), residual "
            << a->residual_px << " px, confidence " << a->confidence << "; from (6, -13): ("
            << b->correction.dx_px << ", " << b->correction.dy_px << "), misregistration "
            << b->misregistration_px << " px, confidence " << b->confidence << "\n";
  // The dump's own calibration is right to within the registration check's (-1, 0).
  EXPECT_TRUE(a->ok) << a->why;
  EXPECT_LT(a->misregistration_px, 2.5);
  // Started 14 px off, the estimate comes back to the same registration.
  EXPECT_TRUE(b->ok) << b->why;
  EXPECT_GT(b->misregistration_px, 11.0);
  EXPECT_LT(registration_distance_px(a->correction, b->correction), 1.0);
}

TEST(CalibrationStore, SavesAndLoadsPerUnit) {
  test::TempDir dir("calstore");
  const CalibrationStore store(dir.path());
  KinectCalibration c = KinectCalibration::defaults();
  c.correction.dx_px = 3.25;
  c.correction.depth_scale = 1.03;
  auto none = store.load("replay:/a/b");
  ASSERT_TRUE(none);
  EXPECT_FALSE(none->has_value());
  ASSERT_TRUE(store.save("replay:/a/b", c));
  auto loaded = store.load("replay:/a/b");
  ASSERT_TRUE(loaded && loaded->has_value());
  EXPECT_DOUBLE_EQ((*loaded)->correction.dx_px, 3.25);
  EXPECT_DOUBLE_EQ((*loaded)->correction.depth_scale, 1.03);
  EXPECT_NE(store.path_for("replay:/a/b"), store.path_for("replay:/a/c"));
}

TEST(CalibratedCamera, RederivesDepthUnderTheNewLaw) {
  // A unit whose true depth law is 4 % longer: the camera reports the defaults; wrapped with
  // the true calibration, depth matches the rendered truth again.
  auto camera = open_camera("synthetic:seed=2,frames=2,depth_scale=1.04,noise=off,motion=static");
  ASSERT_TRUE(camera) << camera.error().message;
  const FrameTruth* truth_source = nullptr;
  KinectCalibration truth = KinectCalibration::defaults();
  truth.correction.depth_scale = 1.04;
  auto wrapped = CalibratedCamera::wrap(std::move(*camera), truth, "test");
  ASSERT_TRUE(wrapped) << wrapped.error().message;
  ASSERT_TRUE((*wrapped)->start());
  RgbdFrame frame;
  auto got = (*wrapped)->next_frame(frame, std::chrono::milliseconds(100));
  ASSERT_TRUE(got && *got == FrameStatus::kFrame);
  truth_source = frame_truth(**wrapped);
  ASSERT_NE(truth_source, nullptr);
  double sum = 0;
  int n = 0;
  for (std::size_t i = 0; i < frame.depth_mm.pixels.size(); ++i) {
    const float z = truth_source->noiseless_depth_mm.pixels[i];
    if (z <= 0 || frame.depth_mm.pixels[i] == 0 || z > 1000) continue;
    sum += frame.depth_mm.pixels[i] - z;
    ++n;
  }
  ASSERT_GT(n, 1000);
  EXPECT_LT(std::abs(sum / n), 1.0) << "mean depth error " << sum / n << " mm";
  EXPECT_DOUBLE_EQ((*wrapped)->info().calibration.correction.depth_scale, 1.04);
}

}  // namespace
}  // namespace fb
