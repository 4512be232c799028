// The `freenect` camera backend: a Kinect v1 through libfreenect's asynchronous API over libusb.
//
// URI: `freenect:N[,calib=PATH][,stall_ms=MS]`
//   N         device index (default 0), as listed by `facebooth camera list`
//   calib     a device.json (fakenect/replay format) with the registration block to use instead
//             of the one read from the device
//   stall_ms  how long next_frame() tolerates no frames at all before it reports the device as
//             stalled or unplugged (default 3000)
//
// Depth is always requested as FREENECT_DEPTH_11BIT and converted to millimetres by the project's
// KinectRegistration: Debian's fakenect (libfreenect 0.5.3) supports no other depth mode and lacks
// the registration symbols, and the same code path must work on the device and under fakenect.
//
// Running under fakenect (LD_LIBRARY_PATH=/usr/lib/<triplet>/fakenect FAKENECT_PATH=DIR) plays
// the dump DIR through the real libfreenect API. The dump is validated before fakenect sees it,
// because fakenect calls exit(1) on a missing INDEX.txt or a missing file. Its end is reported as
// FrameStatus::kEndOfStream. Debian's fakenect keeps its INDEX.txt position in static state that
// freenect_shutdown() does not reset, so a dump plays once per process.
#pragma once

#include "drivers/camera/camera_backend.hpp"

namespace fb {

CameraBackend freenect_camera_backend();

}  // namespace fb
