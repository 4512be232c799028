// Opening a camera and reading frames, shared by the camera and bench commands.
#pragma once

#include <memory>
#include <string>

#include "drivers/camera/depth_camera.hpp"

namespace fb::cli {

// open_camera + start, with the URI in the error message.
Result<std::unique_ptr<DepthCamera>> open_started_camera(const std::string& uri);

// Reads frames until frame number `index` (0-based) is in `frame`.
Result<void> read_frame_at(DepthCamera& camera, long long index, RgbdFrame& frame);

}  // namespace fb::cli
