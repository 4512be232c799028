// The `openni2` camera backend: live OpenNI2 devices and `.oni` recordings played through
// OpenNI2's libOniFile driver.
//
// URIs:
//   openni2:             the first device OpenNI2 finds
//   openni2:URI          a device by its OpenNI URI (as `facebooth camera list` prints it)
//   openni2:PATH.oni     a recording; also any existing regular file
//   openni2:PATH.oni,loop=1,realtime=1   options as replay's (camera_uri.hpp): loop starts over
//                        at the end instead of kEndOfStream, realtime paces frames at their
//                        recorded times; other options are errors listing the accepted ones
//
// What it delivers: depth in millimetres straight from PIXEL_FORMAT_DEPTH_1_MM (100 um depth is
// divided by 10), so RgbdFrame::raw_disparity stays empty; colour from RGB888. Depth and colour
// are not registered (image registration is left off; the project registers itself).
// Intrinsics come from the depth stream's field of view; the Kinect calibration is
// KinectCalibration::defaults() because OpenNI2 does not expose the device's reg_info.
//
// Recordings are stepped manually (PlaybackControl::setSpeed(-1)): each next_frame() reads the
// next depth frame and the colour frame recorded with it, as fast as the caller consumes them,
// without dropping any (realtime=1 holds each until its recorded time is due). After the last
// frame next_frame() returns kEndOfStream (a recording plays once per open), or with loop=1 the
// first frame again.
#pragma once

#include <memory>
#include <string_view>

#include "drivers/camera/camera_backend.hpp"

namespace fb {

CameraBackend openni2_camera_backend();

// The backend's open function, for callers (and tests) that link this backend directly.
// `arguments` is the part after `openni2:`.
Result<std::unique_ptr<DepthCamera>> open_openni2_camera(std::string_view arguments);

}  // namespace fb
