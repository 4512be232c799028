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

// Per-frame ground truth, filled only by the synthetic backend.
struct FrameTruth {
  RigidPose camera_from_model;                      // model frame (mm) -> depth camera frame (mm)
  std::vector<float> identity_coeffs;               // model identity coefficients (sigma units)
  std::vector<float> expression_weights;            // one per model expression shape
  std::vector<Eigen::Vector3d> landmarks_3d;        // 68 iBUG points, depth camera frame, mm
  std::vector<Eigen::Vector2d> landmarks_depth_px;  // 68 points projected into the depth image
  std::vector<Eigen::Vector2d> landmarks_color_px;  // 68 points in the colour image
  Image<float> noiseless_depth_mm;  // rendered depth before the sensor model, 0 = background/none
  // Fraction of the face (jaw line and brows polygon) hidden by a hand in front of it.
  double face_hidden_fraction = 0.0;
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

  // Ground truth of the frame last returned, or nullptr when the backend has none.
  virtual const FrameTruth* truth() const { return nullptr; }

 protected:
  DepthCamera() = default;
};

// One line of `facebooth camera list`.
struct CameraListing {
  std::string uri;
  std::string description;
};

// Opens a camera from a URI such as `synthetic:seed=3,expr=mouthSmile_L`, `replay:PATH`,
// `freenect:0`, `openni2:PATH.oni` or `openni2:` (first live device). Only backends that
// were built are accepted; the error lists those that are.
Result<std::unique_ptr<DepthCamera>> open_camera(std::string_view uri);

// Backends compiled into this build, e.g. {"synthetic", "replay", "freenect", "openni2"}.
std::vector<std::string> built_camera_backends();

// Devices and sources that can be opened now (live devices enumerated by their backends,
// plus the always-available synthetic source).
std::vector<CameraListing> list_cameras();

}  // namespace fb
