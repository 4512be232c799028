#include "drivers/camera/common/calibrated_camera.hpp"

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <system_error>

#include "drivers/camera/common/camera_uri.hpp"
#include "drivers/camera/common/device_json.hpp"

namespace fb {

const char* to_string(CalibrationSource source) {
  switch (source) {
    case CalibrationSource::kDevice:
      return "device";
    case CalibrationSource::kDefaults:
      return "defaults";
    case CalibrationSource::kCheckerboard:
      return "checkerboard";
    case CalibrationSource::kSelfCalibration:
      return "self-calibration";
  }
  return "unknown";
}

CalibratedCamera::CalibratedCamera(std::unique_ptr<DepthCamera> inner,
                                   const KinectCalibration& calibration)
    : inner_(std::move(inner)), info_(inner_->info()), registration_(calibration) {
  info_.calibration = calibration;
  info_.depth_intrinsics = calibration.depth_intrinsics();
  inner_has_correction_ = !inner_->info().calibration.correction.is_identity();
}

Result<std::unique_ptr<CalibratedCamera>> CalibratedCamera::wrap(
    std::unique_ptr<DepthCamera> inner, const KinectCalibration& calibration, std::string note) {
  if (!inner) return fail("calibrated camera: no camera to wrap");
  const auto& z = calibration.zero_plane_info;
  if (!(z.reference_pixel_size > 0.0 && z.reference_distance > 0.0)) {
    return fail(
        "calibrated camera: the calibration's zero-plane values are not positive; "
        "recalibrate the camera (facebooth camera calibrate)");
  }
  auto camera =
      std::unique_ptr<CalibratedCamera>(new CalibratedCamera(std::move(inner), calibration));
  if (!note.empty()) camera->info_.description += ", calibration from " + note;
  return camera;
}

void CalibratedCamera::set_calibration(const KinectCalibration& calibration) {
  registration_ = KinectRegistration(calibration);
  info_.calibration = calibration;
  info_.depth_intrinsics = calibration.depth_intrinsics();
}

Result<FrameStatus> CalibratedCamera::next_frame(RgbdFrame& frame,
                                                 std::chrono::milliseconds timeout) {
  auto status = inner_->next_frame(frame, timeout);
  if (!status || *status != FrameStatus::kFrame) return status;
  if (!frame.raw_disparity.empty()) {
    registration_.disparity_to_mm(frame.raw_disparity, frame.depth_mm);
    return status;
  }
  // No raw disparity (OpenNI2 delivers millimetres): put the millimetres through the
  // correction's depth law relative to what the inner camera applied.
  const RegistrationCorrection& c = info_.calibration.correction;
  if (c.depth_scale == 1.0 && c.inverse_depth_offset_per_m == 0.0 && !inner_has_correction_)
    return status;
  for (auto& mm : frame.depth_mm.pixels) {
    if (mm == 0) continue;
    const double z = c.corrected_mm(mm);
    mm = z >= 1.0 && z < 65535.0 ? static_cast<std::uint16_t>(z + 0.5) : 0;
  }
  return status;
}

std::string calibration_key(const CameraInfo& info) {
  auto uri = parse_camera_uri(info.uri);
  if (!uri) return info.uri;
  if (uri->backend == "replay" || uri->backend == "openni2") {
    // A recording is named by its canonical path (options after a comma are not part of it).
    const std::string path = uri->arguments.substr(0, uri->arguments.find(','));
    std::error_code ec;
    const auto canonical = std::filesystem::weakly_canonical(path, ec);
    return uri->backend + ":" + (ec ? path : canonical.string());
  }
  if (uri->backend == "freenect") {
    // The description names the serial when the device reports one.
    const auto at = info.description.find("serial ");
    if (at != std::string::npos) {
      const auto end = info.description.find_first_of(",) ", at + 7);
      return "freenect:" + info.description.substr(at + 7, end - at - 7);
    }
  }
  return info.uri;
}

CalibrationStore::CalibrationStore(std::filesystem::path directory)
    : directory_(std::move(directory)) {}

CalibrationStore CalibrationStore::user_default() {
  if (const char* dir = std::getenv("FACEBOOTH_CALIBRATION_DIR"); dir && *dir)
    return CalibrationStore(dir);
  if (const char* state = std::getenv("XDG_STATE_HOME"); state && *state)
    return CalibrationStore(std::filesystem::path(state) / "facebooth" / "calibration");
  const char* home = std::getenv("HOME");
  return CalibrationStore(std::filesystem::path(home && *home ? home : ".") / ".local" / "state" /
                          "facebooth" / "calibration");
}

std::filesystem::path CalibrationStore::path_for(const std::string& key) const {
  // A readable prefix and a hash: keys hold path separators and colons.
  std::string readable;
  for (char ch : key) {
    const bool plain = (ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') ||
                       (ch >= '0' && ch <= '9') || ch == '-' || ch == '_';
    readable += plain ? ch : '_';
    if (readable.size() >= 40) break;
  }
  std::uint64_t h = 1469598103934665603ull;  // FNV-1a: the same name on every build
  for (unsigned char ch : key) h = (h ^ ch) * 1099511628211ull;
  char hash[17];
  std::snprintf(hash, sizeof hash, "%016llx", static_cast<unsigned long long>(h));
  return directory_ / (readable + "-" + hash + ".json");
}

Result<std::optional<KinectCalibration>> CalibrationStore::load(const std::string& key) const {
  const auto file = path_for(key);
  std::error_code ec;
  if (!std::filesystem::exists(file, ec)) return std::optional<KinectCalibration>{};
  auto c = read_device_json(file);
  if (!c) {
    return fail("the stored calibration " + file.string() + " is unreadable (" + c.error().message +
                "); delete it and calibrate the camera again");
  }
  return std::optional<KinectCalibration>(*c);
}

Result<void> CalibrationStore::save(const std::string& key,
                                    const KinectCalibration& calibration) const {
  std::error_code ec;
  std::filesystem::create_directories(directory_, ec);
  if (ec) {
    return fail("cannot create the calibration directory " + directory_.string() + ": " +
                ec.message() + "; set FACEBOOTH_CALIBRATION_DIR to a writable directory");
  }
  return write_device_json(path_for(key), calibration);
}

}  // namespace fb
