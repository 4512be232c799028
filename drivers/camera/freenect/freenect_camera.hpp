#pragma once
#include "drivers/camera/camera_backend.hpp"
namespace fb {
CameraBackend freenect_camera_backend();
}  // namespace fb
