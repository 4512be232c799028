// The `device.json` calibration file that accompanies a fakenect dump (as written by the
// OpenISS/libfreenect recorder and by FakenectDumpWriter):
//
//   {"reg_info": {"ax": ..., ..., "dydydy_start": ...,
//                 "pad_info": {"start_lines", "end_lines", "cropping_lines"},
//                 "zero_plane_info": {"dcmos_emitter_distance", "dcmos_rcmos_distance",
//                                     "reference_distance", "reference_pixel_size"}},
//    "const_shift": 200}
//
// pad_info and zero_plane_info are nested inside reg_info in the real files; the parser also
// accepts them at the top level. facebooth adds an optional top-level "correction" object
// (RegistrationCorrection: dx_px, dy_px, rotation_deg, depth_scale, inverse_depth_offset_per_m),
// written only when the unit has been calibrated; other readers ignore it.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>

#include "algo/core/result.hpp"
#include "algo/sensor/kinect_calibration.hpp"

namespace fb {

// Parses device.json text. Every field is required; errors name the missing or mistyped field
// (e.g. "device.json: field 'reg_info.dx_start' is missing").
Result<KinectCalibration> parse_device_json(std::string_view text);

// Writes device.json text in the same layout as the real dumps; parse_device_json() of the
// result gives back exactly `calibration` (doubles are written with round-trip precision).
std::string to_device_json(const KinectCalibration& calibration);

// File helpers: read and parse `file`, or write it (complete file, then renamed into place).
Result<KinectCalibration> read_device_json(const std::filesystem::path& file);
Result<void> write_device_json(const std::filesystem::path& file,
                               const KinectCalibration& calibration);

}  // namespace fb
