// `replay:DIR[,realtime=1][,loop=1]`: plays a fakenect dump directory (a real Kinect recording
// or one made by FakenectRecorder) as a DepthCamera.
//
// - Calibration: DIR/device.json when present, else KinectCalibration::defaults().
// - Frames: one per depth image, colour = latest colour image (see fakenect_dump.hpp);
//   raw_disparity is kept and depth_mm is computed with KinectRegistration.
// - Timing: as fast as the caller asks by default; `realtime=1` paces frames at the recorded
//   host-time intervals. `loop=1` starts over at the end instead of reporting kEndOfStream.
// - start() (re)starts at the first frame.
#pragma once

#include <filesystem>
#include <memory>

#include "drivers/camera/camera_backend.hpp"
#include "drivers/camera/common/camera_uri.hpp"

namespace fb {

using ReplayOptions = RecordingOptions;  // realtime, loop (camera_uri.hpp)

// Opens a dump directly (the `replay:` URI parses into this).
Result<std::unique_ptr<DepthCamera>> open_replay_camera(const std::filesystem::path& directory,
                                                        const ReplayOptions& options = {});

CameraBackend replay_camera_backend();

}  // namespace fb
