#include "sim/subject/unit_calibration.hpp"

#include <chrono>
#include <string>

#include "algo/sensor/self_calibration.hpp"
#include "sim/camera/world_presets.hpp"

namespace fb::cli {

Result<UnitCalibration> parse_unit_calibration(std::string_view name) {
  if (name.empty() || name == "self") return UnitCalibration::kSelfCalibrated;
  if (name == "self-depth-law") return UnitCalibration::kSelfWithDepthLaw;
  if (name == "reported") return UnitCalibration::kAsReported;
  if (name == "calibrated") return UnitCalibration::kCalibrated;
  return fail("unknown unit calibration '" + std::string(name) +
              "': use self (self-calibrate a decalibrated unit, the default), self-depth-law (the "
              "depth law known, the registration self-calibrated), reported (use "
              "what the unit reports) or calibrated (the unit's true calibration)");
}

const char* unit_calibration_name(UnitCalibration mode) {
  switch (mode) {
    case UnitCalibration::kSelfCalibrated:
      return "self";
    case UnitCalibration::kSelfWithDepthLaw:
      return "self-depth-law";
    case UnitCalibration::kAsReported:
      return "reported";
    case UnitCalibration::kCalibrated:
      return "calibrated";
  }
  return "self";
}

Result<KinectCalibration> unit_calibration_for(const FaceModel& model, SyntheticOptions& options,
                                               UnitCalibration mode) {
  if (!options.reported_calibration) return options.calibration;  // a calibrated unit
  if (mode == UnitCalibration::kCalibrated) {
    options.reported_calibration.reset();
    return options.calibration;
  }
  if (mode == UnitCalibration::kSelfWithDepthLaw) {
    // The camera reads depth with the unit's true law; only its registration is the default.
    auto& law = options.reported_calibration->correction;
    law.depth_scale = options.calibration.correction.depth_scale;
    law.inverse_depth_offset_per_m = options.calibration.correction.inverse_depth_offset_per_m;
  }
  const KinectCalibration reported = *options.reported_calibration;
  if (mode == UnitCalibration::kAsReported) return reported;
  // An earlier take of the same unit and scene: a head turn, other noise.
  SyntheticOptions take = options;
  take.frame_count = 45;
  take.motion = SyntheticMotion::kHeadTurn;
  take.seed = options.seed ^ 0x5e1fca1b;
  take.camera_from_model_track.clear();
  auto camera = make_synthetic_camera(model, take);
  if (!camera) return camera.failure();
  if (auto started = (*camera)->start(); !started) return started.failure();
  SelfCalibrator calibrator(reported);
  RgbdFrame frame;
  for (int i = 0; i < take.frame_count; ++i) {
    auto got = (*camera)->next_frame(frame, std::chrono::milliseconds(1000));
    if (!got) return got.failure();
    if (*got != FrameStatus::kFrame) break;
    calibrator.add_frame(frame.depth_mm, frame.color);
  }
  auto estimate = calibrator.estimate();
  if (!estimate) return estimate.failure();
  if (!estimate->ok) return fail("self-calibration of the synthetic unit failed: " + estimate->why);
  return with_registration(reported, estimate->correction);
}

bool decalibrates_unit(std::string_view part) {
  if (part.empty() || part == "baseline") return false;
  SyntheticOptions probe;
  return apply_world_preset(part, 1, probe).ok() && probe.reported_calibration.has_value();
}

nlohmann::json ratio_of(const nlohmann::json& a, const nlohmann::json& b) {
  if (!a.is_number() || !b.is_number() || !(b.get<double>() > 0.0)) return nullptr;
  return a.get<double>() / b.get<double>();
}

}  // namespace fb::cli
