#pragma once
#include "drivers/camera/camera_backend.hpp"
namespace fb {
CameraBackend synthetic_camera_backend();
}  // namespace fb
