// Records frames from any camera backend as a fakenect dump (fakenect_dump.hpp), so recordings
// play back with `replay:DIR` and with libfreenect's fakenect.
//
// Depth is stored as raw 11-bit disparity: frame.raw_disparity when the backend has it, else
// frame.depth_mm converted with KinectRegistration::mm_to_disparity (quantised to the nearest
// raw value of the camera's calibration, as a real Kinect would). device.json gets
// CameraInfo::calibration. A colour image is written only when it changed (new colour host time
// or device timestamp; every frame when the backend leaves both at 0), before the depth image it
// belongs to, so replay pairs them the same way.
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>

#include "algo/sensor/kinect_calibration.hpp"
#include "drivers/camera/common/fakenect_dump.hpp"
#include "drivers/camera/depth_camera.hpp"

namespace fb {

struct RecorderOptions {
  bool overwrite = false;  // allow recording into a non-empty directory (see DumpWriterOptions)
  bool sync_each_entry = false;  // fsync every file (power-loss safe, slow)
  // record_camera(): wait per next_frame() call, and how many timeouts in a row end the
  // recording with an error (a live camera that stopped delivering).
  std::chrono::milliseconds frame_timeout{1000};
  int max_consecutive_timeouts = 10;
};

struct RecordSummary {
  std::filesystem::path directory;
  long long depth_frames = 0;
  long long color_images = 0;
  bool end_of_stream = false;  // the source ended (rather than max_frames being reached)
  double first_host_time_s = 0.0;
  double last_host_time_s = 0.0;
};

class FakenectRecorder {
 public:
  // Creates the dump directory, device.json (from camera.calibration) and INDEX.txt.
  static Result<FakenectRecorder> create(const std::filesystem::path& directory,
                                         const CameraInfo& camera,
                                         const RecorderOptions& options = {});

  FakenectRecorder(FakenectRecorder&&) noexcept;
  FakenectRecorder& operator=(FakenectRecorder&&) noexcept;
  ~FakenectRecorder();

  // Appends one frame (its colour first when new, then its depth). Frames without a host time
  // (0) get index / fps so the dump still plays at the camera's rate. Steady state does not
  // allocate.
  Result<void> write(const RgbdFrame& frame);
  // Closes INDEX.txt. The dump is valid after every write(), finish() only seals it.
  Result<RecordSummary> finish();
  const RecordSummary& summary() const;

 private:
  struct State;
  explicit FakenectRecorder(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;
};

// Starts `camera`, records up to `max_frames` frames (<= 0: until the end of the stream) into
// `directory`, calls `progress(frames_so_far)` after each frame (may be empty), stops the camera.
// On an error the frames recorded so far remain a valid dump; the error says how many there are.
Result<RecordSummary> record_camera(DepthCamera& camera, const std::filesystem::path& directory,
                                    long long max_frames,
                                    const std::function<void(long long)>& progress,
                                    const RecorderOptions& options = {});

}  // namespace fb
