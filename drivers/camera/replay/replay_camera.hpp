#pragma once
#include "drivers/camera/camera_backend.hpp"
namespace fb {
CameraBackend replay_camera_backend();
}  // namespace fb
