// The one interface every camera backend implements (libcamera-style: the backend owns its
// C handles; callers own the camera through unique_ptr and reuse their frame buffers).
#pragma once

#include <chrono>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "algo/core/camera_model.hpp"
#include "algo/core/frame.hpp"
#include "algo/core/result.hpp"
#include "algo/sensor/kinect_calibration.hpp"
#include "drivers/camera/camera_controls.hpp"

namespace fb {

struct CameraInfo {
  std::string uri;          // the URI the camera was opened with
  std::string backend;      // "synthetic", "replay", "freenect", "openni2"
  std::string description;  // human readable: device serial, dump path, seed...
  int width = kKinectWidth;
  int height = kKinectHeight;
  double fps = kKinectFps;
  KinectCalibration calibration;  // used for disparity conversion and registration
  PinholeIntrinsics depth_intrinsics;
  long long frame_count = -1;  // known length of a recording or synthetic take, -1 = live
};

enum class FrameStatus {
  kFrame,        // `frame` holds a new frame
  kTimeout,      // nothing arrived within the timeout; try again
  kEndOfStream,  // a recording or synthetic take has ended; no more frames will come
};

class DepthCamera {
 public:
  virtual ~DepthCamera() = default;
  DepthCamera(const DepthCamera&) = delete;
  DepthCamera& operator=(const DepthCamera&) = delete;

  virtual const CameraInfo& info() const = 0;
  virtual Result<void> start() = 0;
  virtual void stop() = 0;

  // Waits up to `timeout` for the next frame and writes it into `frame`, reusing its buffers.
  // Errors (device unplugged, unreadable file) are failures; the end of a recording is not.
  virtual Result<FrameStatus> next_frame(RgbdFrame& frame, std::chrono::milliseconds timeout) = 0;

 protected:
  DepthCamera() = default;
};

// One line of `facebooth camera list`.
struct CameraListing {
  std::string uri;
  std::string description;
};

// Opens a camera from a URI such as `replay:PATH`, `freenect:0`, `openni2:PATH.oni`,
// `openni2:` (first live device) or, through a loadable module (camera_plugin.hpp),
// `synthetic:seed=3,expr=mouthSmile_L`. `controls` (camera_controls.hpp) override the URI; a
// control the backend does not take is an error. `resources` are lent to a backend that uses
// them (a face model to render with). The error for an unknown backend lists those there are.
Result<std::unique_ptr<DepthCamera>> open_camera(std::string_view uri,
                                                 const CameraControls& controls = {},
                                                 const CameraResources& resources = {});

// Whether the backend of `uri` takes `control` (false when the backend is unknown).
bool camera_has_control(std::string_view uri, std::string_view control);

// Backends this binary can open: built in, then loadable modules, e.g. {"replay", "freenect",
// "openni2", "synthetic"}.
std::vector<std::string> built_camera_backends();

// Devices and sources that can be opened now (live devices enumerated by their backends,
// plus what the modules offer, e.g. the synthetic source).
std::vector<CameraListing> list_cameras();

}  // namespace fb
