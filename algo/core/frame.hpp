// One RGB-D frame as every camera backend delivers it.
#pragma once

#include <cstdint>

#include "algo/core/image.hpp"

namespace fb {

inline constexpr int kKinectWidth = 640;
inline constexpr int kKinectHeight = 480;
inline constexpr double kKinectFps = 30.0;

struct RgbdFrame {
  std::uint64_t index = 0;  // 0-based position in the stream

  // Host time in seconds (as in fakenect file names) and the device's 32-bit
  // 60 MHz clock, for depth and colour separately (they are not captured together).
  double depth_host_time_s = 0.0;
  double color_host_time_s = 0.0;
  std::uint32_t depth_device_timestamp = 0;
  std::uint32_t color_device_timestamp = 0;

  // Depth in the depth (IR) camera's image, millimetres, 0 = invalid. Not registered.
  DepthImage depth_mm;
  // Raw 11-bit disparity when the backend has it (freenect, replay, synthetic);
  // empty when it does not (openni2 delivers millimetres only).
  DisparityImage raw_disparity;
  // Colour camera image, RGB8.
  ColorImage color;
};

}  // namespace fb
