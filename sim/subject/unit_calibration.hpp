// How the laboratory's synthetic takes get the registration a decalibrated unit is used with:
// as the product does without a device.json (self-calibration from an earlier take of the same
// unit), as the unit reports it (its defaults: what happened before self-calibration), or the
// unit's truth (a perfectly calibrated unit, the reference the self-calibrated run is held to).
#pragma once

#include <string_view>

#include <nlohmann/json.hpp>

#include "algo/core/result.hpp"
#include "algo/facemodel/face_model.hpp"
#include "algo/sensor/kinect_calibration.hpp"
#include "sim/camera/synthetic_camera.hpp"

namespace fb::cli {

// kSelfWithDepthLaw: the unit's depth law is known (a checkerboard device.json made once) and
// the registration is self-calibrated, the split self-calibration can serve: the depth law is
// not observable from ordinary frames (docs/calibration.md).
enum class UnitCalibration { kSelfCalibrated, kSelfWithDepthLaw, kAsReported, kCalibrated };

// "self" | "self-depth-law" | "reported" | "calibrated".
Result<UnitCalibration> parse_unit_calibration(std::string_view name);
const char* unit_calibration_name(UnitCalibration mode);

// Prepares `options` for `mode` (kCalibrated: the camera reports its true calibration) and
// returns the calibration the pipeline should use with the camera made from them. For
// kSelfCalibrated on a decalibrated unit, a 45-frame head turn of the same scene is rendered
// and self-calibrated; a unit the self-calibration cannot calibrate is an error (never used).
Result<KinectCalibration> unit_calibration_for(const FaceModel& model, SyntheticOptions& options,
                                               UnitCalibration mode);

// Whether world scenario `part` (world_presets.hpp) renders through a decalibrated unit.
bool decalibrates_unit(std::string_view part);

// a / b for two JSON figures; null when either is missing or b is not positive.
nlohmann::json ratio_of(const nlohmann::json& a, const nlohmann::json& b);

// The help text of the --unit-calibration option the evals share.
inline constexpr const char* kUnitCalibrationHelp =
    "registration a decalibrated unit (scenario part unit) is used with: self (self-calibrated "
    "from an earlier take, as the product does without a device.json), self-depth-law (the "
    "depth law from a checkerboard device.json, the registration self-calibrated), reported "
    "(the unit's defaults) or calibrated (its truth). With self, each such part is also run "
    "self-depth-law and calibrated; decalibrated_vs_calibrated_ratio compares them";

}  // namespace fb::cli
