// The laboratory's measure of self-calibration: seeded decalibrated synthetic units, each
// self-calibrated from a head-turn take and scored against the unit's true registration.
#pragma once

#include <cstdint>
#include <functional>
#include <string>

#include <nlohmann/json.hpp>

#include "algo/core/result.hpp"

namespace fb::cli {

struct SelfCalibrationEvalOptions {
  int units = 100;
  std::uint64_t first_unit = 1;  // unit seeds first_unit .. first_unit + units - 1
  int frames = 45;               // frames of each unit's take
  std::string extra_uri;         // extra synthetic keys for every take (e.g. a scenario)
};

// Fields: units, self_calibration_units_ok, self_calibration_residual_px_p95 (the estimate's
// registration error against the truth over the units reported ok, colour px: where a depth
// pixel at the face's depth lands under the estimate against its true colour position, the
// largest over the image centre and the quadrant centres),
// self_calibration_residual_px_mean, self_calibration_wrongly_ok (ok but > 3 px off: must be 0),
// self_calibration_not_ok (seeds with why), and per-unit rows under self_calibration_units.
Result<nlohmann::ordered_json> evaluate_self_calibration(const SelfCalibrationEvalOptions& options,
                                                         const std::function<void(int)>& progress);

// bench: self-calibration of one 90-frame take (add_frame + estimate, one core) against the
// OpenCV chamfer peer (Canny + distance transform + exhaustive shift search, as the registration
// check test measures) on the same frames. Fields self_calibration_ms, peer_ms, ratio, and both
// errors against the truth.
Result<nlohmann::ordered_json> bench_self_calibration(int frames, std::uint64_t unit);

}  // namespace fb::cli
