// A unit's calibration applied to any camera, and where each unit's calibration is kept.
//
// CalibratedCamera wraps an opened camera and delivers its frames under another calibration:
// depth in millimetres re-derived from the raw disparity with the new disparity law (or, for a
// backend without raw disparity, the millimetres put through the correction's depth law), and
// CameraInfo::calibration replaced, so every registration downstream uses it.
//
// CalibrationStore keeps one device.json per unit in a directory, named by the unit's key
// (a live device's serial, a recording's canonical path, a synthetic URI), so the next run of
// the same unit starts from what the last one learned.
#pragma once

#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include "algo/core/result.hpp"
#include "algo/sensor/kinect_calibration.hpp"
#include "drivers/camera/depth_camera.hpp"

namespace fb {

// Where a unit's calibration came from, for messages and the status.
enum class CalibrationSource {
  kDevice,           // the device's firmware tables or a device.json next to the recording
  kDefaults,         // the built-in defaults: nothing better was known
  kCheckerboard,     // `facebooth camera calibrate`
  kSelfCalibration,  // estimated from ordinary frames
};
const char* to_string(CalibrationSource source);

class CalibratedCamera : public DepthCamera {
 public:
  // Takes ownership of `inner`. Fails when the calibration's tables cannot be built.
  static Result<std::unique_ptr<CalibratedCamera>> wrap(std::unique_ptr<DepthCamera> inner,
                                                        const KinectCalibration& calibration,
                                                        std::string note);

  const CameraInfo& info() const override { return info_; }
  Result<void> start() override { return inner_->start(); }
  void stop() override { inner_->stop(); }
  Result<FrameStatus> next_frame(RgbdFrame& frame, std::chrono::milliseconds timeout) override;

  // Replaces the calibration from the next frame on (e.g. after self-calibration).
  void set_calibration(const KinectCalibration& calibration);
  DepthCamera& inner() { return *inner_; }
  const DepthCamera& inner() const { return *inner_; }

 private:
  CalibratedCamera(std::unique_ptr<DepthCamera> inner, const KinectCalibration& calibration);
  std::unique_ptr<DepthCamera> inner_;
  CameraInfo info_;
  KinectRegistration registration_;
  bool inner_has_correction_ = false;
};

// The key that names a unit: `freenect:SERIAL`, `replay:/canonical/path`, the synthetic URI.
std::string calibration_key(const CameraInfo& info);

class CalibrationStore {
 public:
  explicit CalibrationStore(std::filesystem::path directory);
  // $FACEBOOTH_CALIBRATION_DIR, else $XDG_STATE_HOME/facebooth/calibration, else
  // ~/.local/state/facebooth/calibration.
  static CalibrationStore user_default();

  const std::filesystem::path& directory() const { return directory_; }
  std::filesystem::path path_for(const std::string& key) const;

  // The stored calibration of this unit, or nullopt when none was stored.
  Result<std::optional<KinectCalibration>> load(const std::string& key) const;
  // Writes atomically (temporary file + rename); creates the directory.
  Result<void> save(const std::string& key, const KinectCalibration& calibration) const;

 private:
  std::filesystem::path directory_;
};

}  // namespace fb
