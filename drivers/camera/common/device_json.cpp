#include "drivers/camera/common/device_json.hpp"

#include <cmath>
#include <cstdint>
#include <fstream>
#include <limits>
#include <sstream>
#include <system_error>

#include <nlohmann/json.hpp>

namespace fb {
namespace {

using nlohmann::json;

// Field tables so the parser and the writer cannot drift apart.
struct IntField {
  const char* name;
  std::int32_t KinectRegInfo::*member;
};
constexpr IntField kRegFields[] = {
    {"ax", &KinectRegInfo::ax},
    {"bx", &KinectRegInfo::bx},
    {"cx", &KinectRegInfo::cx},
    {"dx", &KinectRegInfo::dx},
    {"ay", &KinectRegInfo::ay},
    {"by", &KinectRegInfo::by},
    {"cy", &KinectRegInfo::cy},
    {"dy", &KinectRegInfo::dy},
    {"dx_start", &KinectRegInfo::dx_start},
    {"dy_start", &KinectRegInfo::dy_start},
    {"dx_beta_start", &KinectRegInfo::dx_beta_start},
    {"dy_beta_start", &KinectRegInfo::dy_beta_start},
    {"dx_beta_inc", &KinectRegInfo::dx_beta_inc},
    {"dy_beta_inc", &KinectRegInfo::dy_beta_inc},
    {"dxdx_start", &KinectRegInfo::dxdx_start},
    {"dxdy_start", &KinectRegInfo::dxdy_start},
    {"dydx_start", &KinectRegInfo::dydx_start},
    {"dydy_start", &KinectRegInfo::dydy_start},
    {"dxdxdx_start", &KinectRegInfo::dxdxdx_start},
    {"dydxdx_start", &KinectRegInfo::dydxdx_start},
    {"dxdxdy_start", &KinectRegInfo::dxdxdy_start},
    {"dydxdy_start", &KinectRegInfo::dydxdy_start},
    {"dydydx_start", &KinectRegInfo::dydydx_start},
    {"dydydy_start", &KinectRegInfo::dydydy_start},
};

struct PadField {
  const char* name;
  std::int32_t KinectPadInfo::*member;
};
constexpr PadField kPadFields[] = {
    {"start_lines", &KinectPadInfo::start_lines},
    {"end_lines", &KinectPadInfo::end_lines},
    {"cropping_lines", &KinectPadInfo::cropping_lines},
};

struct ZeroPlaneField {
  const char* name;
  double KinectZeroPlaneInfo::*member;
};
constexpr ZeroPlaneField kZeroPlaneFields[] = {
    {"dcmos_emitter_distance", &KinectZeroPlaneInfo::dcmos_emitter_distance},
    {"dcmos_rcmos_distance", &KinectZeroPlaneInfo::dcmos_rcmos_distance},
    {"reference_distance", &KinectZeroPlaneInfo::reference_distance},
    {"reference_pixel_size", &KinectZeroPlaneInfo::reference_pixel_size},
};

struct CorrectionField {
  const char* name;
  double RegistrationCorrection::*member;
};
constexpr CorrectionField kCorrectionFields[] = {
    {"dx_px", &RegistrationCorrection::dx_px},
    {"dy_px", &RegistrationCorrection::dy_px},
    {"rotation_deg", &RegistrationCorrection::rotation_deg},
    {"depth_scale", &RegistrationCorrection::depth_scale},
    {"inverse_depth_offset_per_m", &RegistrationCorrection::inverse_depth_offset_per_m},
};

const char* type_name(const json& v) {
  return v.type_name();
}

Result<std::int32_t> get_int(const json& object, const std::string& path, const char* name) {
  const auto it = object.find(name);
  const std::string full = path + name;
  if (it == object.end()) return fail("device.json: field '" + full + "' is missing");
  if (!it->is_number_integer()) {
    return fail("device.json: field '" + full + "' must be an integer, found " + type_name(*it));
  }
  // Integers in the file are the device's 32-bit fields; accept both signed and the unsigned
  // spelling of the same bit pattern.
  if (it->is_number_unsigned()) {
    const auto u = it->get<std::uint64_t>();
    if (u > std::numeric_limits<std::uint32_t>::max()) {
      return fail("device.json: field '" + full + "' = " + std::to_string(u) +
                  " does not fit in 32 bits");
    }
    return static_cast<std::int32_t>(static_cast<std::uint32_t>(u));
  }
  const auto s = it->get<std::int64_t>();
  if (s < std::numeric_limits<std::int32_t>::min() ||
      s > std::numeric_limits<std::int32_t>::max()) {
    return fail("device.json: field '" + full + "' = " + std::to_string(s) +
                " does not fit in 32 bits");
  }
  return static_cast<std::int32_t>(s);
}

Result<double> get_number(const json& object, const std::string& path, const char* name) {
  const auto it = object.find(name);
  const std::string full = path + name;
  if (it == object.end()) return fail("device.json: field '" + full + "' is missing");
  if (!it->is_number()) {
    return fail("device.json: field '" + full + "' must be a number, found " + type_name(*it));
  }
  return it->get<double>();
}

// Finds a nested object under reg_info (the real layout) or at the top level.
Result<const json*> find_block(const json& root, const json& reg, const char* name) {
  const json* block = nullptr;
  std::string where;
  if (auto it = reg.find(name); it != reg.end()) {
    block = &*it;
    where = std::string("reg_info.") + name;
  } else if (auto top = root.find(name); top != root.end()) {
    block = &*top;
    where = name;
  } else {
    return fail(std::string("device.json: object 'reg_info.") + name + "' is missing");
  }
  if (!block->is_object()) {
    return fail("device.json: field '" + where + "' must be an object, found " + type_name(*block));
  }
  return block;
}

}  // namespace

Result<KinectCalibration> parse_device_json(std::string_view text) {
  json root;
  try {
    root = json::parse(text.begin(), text.end());
  } catch (const json::exception& e) {  // parse_error, and out_of_range for 1e400
    return fail(std::string("device.json is not valid JSON (") + e.what() +
                "); fix or delete the file to use the default Kinect calibration");
  }
  if (!root.is_object()) {
    return fail(std::string("device.json: expected a JSON object at the top level, found ") +
                type_name(root));
  }
  const auto reg_it = root.find("reg_info");
  if (reg_it == root.end()) return fail("device.json: object 'reg_info' is missing");
  if (!reg_it->is_object()) {
    return fail(std::string("device.json: field 'reg_info' must be an object, found ") +
                type_name(*reg_it));
  }
  const json& reg = *reg_it;

  KinectCalibration c;
  for (const auto& f : kRegFields) {
    auto v = get_int(reg, "reg_info.", f.name);
    if (!v) return v.failure();
    c.reg_info.*(f.member) = *v;
  }

  auto pad = find_block(root, reg, "pad_info");
  if (!pad) return pad.failure();
  const std::string pad_path = reg.contains("pad_info") ? "reg_info.pad_info." : "pad_info.";
  for (const auto& f : kPadFields) {
    auto v = get_int(**pad, pad_path, f.name);
    if (!v) return v.failure();
    c.pad_info.*(f.member) = *v;
  }

  auto zpi = find_block(root, reg, "zero_plane_info");
  if (!zpi) return zpi.failure();
  const std::string zpi_path =
      reg.contains("zero_plane_info") ? "reg_info.zero_plane_info." : "zero_plane_info.";
  for (const auto& f : kZeroPlaneFields) {
    auto v = get_number(**zpi, zpi_path, f.name);
    if (!v) return v.failure();
    c.zero_plane_info.*(f.member) = *v;
  }
  // Values that would make the disparity law meaningless (division by zero, negative sizes).
  if (!(c.zero_plane_info.reference_pixel_size > 0.0)) {
    return fail("device.json: field '" + zpi_path + "reference_pixel_size' must be > 0");
  }
  if (!(c.zero_plane_info.reference_distance > 0.0)) {
    return fail("device.json: field '" + zpi_path + "reference_distance' must be > 0");
  }
  if (!(c.zero_plane_info.dcmos_emitter_distance > 0.0)) {
    return fail("device.json: field '" + zpi_path + "dcmos_emitter_distance' must be > 0");
  }

  auto shift = get_int(root, "", "const_shift");
  if (!shift) return shift.failure();
  c.const_shift = *shift;

  // Optional: the unit's correction written by `camera calibrate` or self-calibration.
  if (auto corr = root.find("correction"); corr != root.end()) {
    if (!corr->is_object()) {
      return fail(std::string("device.json: field 'correction' must be an object, found ") +
                  type_name(*corr));
    }
    for (const auto& f : kCorrectionFields) {
      if (!corr->contains(f.name)) continue;  // a missing term is no correction of it
      auto v = get_number(*corr, "correction.", f.name);
      if (!v) return v.failure();
      c.correction.*(f.member) = *v;
    }
    const auto& k = c.correction;
    if (!(k.depth_scale > 0.5 && k.depth_scale < 2.0)) {
      return fail(
          "device.json: field 'correction.depth_scale' must be between 0.5 and 2; "
          "recalibrate the camera (facebooth camera calibrate)");
    }
    if (!(std::abs(k.dx_px) < 100.0 && std::abs(k.dy_px) < 100.0 &&
          std::abs(k.rotation_deg) < 20.0 && std::abs(k.inverse_depth_offset_per_m) < 1.0)) {
      return fail(
          "device.json: the 'correction' block is out of range (|dx_px|, |dy_px| < 100, "
          "|rotation_deg| < 20, |inverse_depth_offset_per_m| < 1); recalibrate the camera");
    }
  }
  return c;
}

std::string to_device_json(const KinectCalibration& c) {
  // nlohmann::ordered_json keeps the field order of the real files, which makes diffs readable.
  nlohmann::ordered_json reg;
  for (const auto& f : kRegFields) reg[f.name] = c.reg_info.*(f.member);
  nlohmann::ordered_json pad;
  for (const auto& f : kPadFields) pad[f.name] = c.pad_info.*(f.member);
  nlohmann::ordered_json zpi;
  for (const auto& f : kZeroPlaneFields) zpi[f.name] = c.zero_plane_info.*(f.member);
  reg["pad_info"] = std::move(pad);
  reg["zero_plane_info"] = std::move(zpi);
  nlohmann::ordered_json root;
  root["reg_info"] = std::move(reg);
  root["const_shift"] = c.const_shift;
  if (!c.correction.is_identity()) {
    nlohmann::ordered_json corr;
    for (const auto& f : kCorrectionFields) corr[f.name] = c.correction.*(f.member);
    root["correction"] = std::move(corr);
  }
  return root.dump(4) + "\n";
}

Result<KinectCalibration> read_device_json(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) {
    return fail("cannot open '" + file.string() + "' for reading; check the path and permissions");
  }
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) return fail("error while reading '" + file.string() + "'");
  auto parsed = parse_device_json(text.str());
  if (!parsed) return fail(file.string() + ": " + parsed.error().message);
  return parsed;
}

Result<void> write_device_json(const std::filesystem::path& file,
                               const KinectCalibration& calibration) {
  // Written to a temporary name and renamed, so a reader never sees half a file.
  std::filesystem::path tmp = file;
  tmp += ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) {
      return fail("cannot create '" + tmp.string() +
                  "'; check that the directory exists and is writable");
    }
    out << to_device_json(calibration);
    out.flush();
    if (!out) return fail("error while writing '" + tmp.string() + "' (disk full?)");
  }
  std::error_code ec;
  std::filesystem::rename(tmp, file, ec);
  if (ec) {
    return fail("cannot rename '" + tmp.string() + "' to '" + file.string() + "': " + ec.message());
  }
  return success();
}

}  // namespace fb
