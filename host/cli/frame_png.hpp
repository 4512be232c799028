// Renders one RGB-D frame as a PNG: false-colour depth beside the colour image, and
// optionally the depth registered onto the colour image, to check alignment by eye.
#pragma once

#include <filesystem>

#include "algo/core/frame.hpp"
#include "algo/core/result.hpp"
#include "algo/sensor/kinect_calibration.hpp"

namespace cv {
class Mat;
}

namespace fb::cli {

// Writes an 8-bit BGR (or grey) image in the format its extension names (PNG, JPEG ...);
// OpenCV's exceptions become errors that name the file.
Result<void> write_image_file(const std::filesystem::path& path, const cv::Mat& image);

struct FramePngOptions {
  // When set, a third panel blends the registered depth's edges over the colour image.
  const KinectRegistration* registration = nullptr;
};

Result<void> write_frame_png(const RgbdFrame& frame, const std::filesystem::path& path,
                             const FramePngOptions& options = {});

}  // namespace fb::cli
