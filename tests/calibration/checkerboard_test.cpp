// Checkerboard calibration against the synthetic board scene's ground truth.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>

#include "algo/calibration/board_detection.hpp"
#include "algo/calibration/checkerboard_calibrator.hpp"
#include "drivers/camera/common/device_json.hpp"
#include "drivers/camera/synthetic/board_scene.hpp"
#include "drivers/camera/synthetic/synthetic_camera.hpp"

namespace fb {
namespace {

struct UnitOutcome {
  RegistrationCorrection truth;
  CheckerboardResult result;
  double corner_error_px_max = 0.0;  // detected vs true colour corners
};

// Renders `views` board views of decalibrated unit `unit` and calibrates.
Result<UnitOutcome> calibrate_unit(std::uint64_t unit, int views, std::uint64_t seed) {
  BoardSceneOptions options;
  options.seed = seed;
  options.frame_count = views;
  options.calibration.correction = random_unit_correction(unit);
  options.reported_calibration = KinectCalibration::defaults();
  auto scene = BoardScene::create(options);
  if (!scene) return scene.failure();
  CheckerboardCalibrator calibrator(options.board, (*scene)->reported_calibration());
  UnitOutcome outcome;
  outcome.truth = options.calibration.correction;
  RgbdFrame frame;
  for (int i = 0; i < views; ++i) {
    BoardViewTruth truth;
    if (auto r = (*scene)->render(i, frame, &truth); !r) return r.failure();
    if (auto added = calibrator.add_frame(frame.color, frame.raw_disparity, frame.depth_mm);
        !added) {
      return fail("view " + std::to_string(i) + ": " + added.error().message);
    }
    const auto& corners = calibrator.board_views().back().corners_color;
    for (std::size_t j = 0; j < corners.size(); ++j) {
      outcome.corner_error_px_max =
          std::max(outcome.corner_error_px_max, (corners[j] - truth.corners_color[j]).norm());
    }
  }
  auto solved = calibrator.solve();
  if (!solved) return solved.failure();
  outcome.result = *solved;
  return outcome;
}

TEST(Checkerboard, RecoversDecalibratedUnits) {
  for (std::uint64_t unit : {1u, 2u, 3u}) {
    auto outcome = calibrate_unit(unit, 12, 100 + unit);
    ASSERT_TRUE(outcome) << outcome.error().message;
    const auto& t = outcome->truth;
    const auto& e = outcome->result.correction;
    const double reg = registration_difference_px(e, t);
    const double depth = std::abs(depth_law_ratio(e, t, 800.0) - 1.0) * 100.0;
    std::printf("unit %llu: truth dx %.3f dy %.3f rot %.4f s %.5f off %.5f\n",
                static_cast<unsigned long long>(unit), t.dx_px, t.dy_px, t.rotation_deg,
                t.depth_scale, t.inverse_depth_offset_per_m);
    std::printf(
        "        est   dx %.3f dy %.3f rot %.4f s %.5f off %.5f  reg %.3f px depth %.3f %%"
        " corners %.3f px rms (max det err %.3f) depth %.2f mm edge %.3f px beta %.3f it %d\n",
        e.dx_px, e.dy_px, e.rotation_deg, e.depth_scale, e.inverse_depth_offset_per_m, reg, depth,
        outcome->result.color_px_rms, outcome->corner_error_px_max, outcome->result.depth_mm_rms,
        outcome->result.edge_px_rms, outcome->result.edge_offset_px, outcome->result.iterations);
    EXPECT_LT(reg, 0.5);
    EXPECT_LT(depth, 0.5);
    EXPECT_LT(outcome->result.color_px_rms, 0.5);
  }
}

}  // namespace
}  // namespace fb
