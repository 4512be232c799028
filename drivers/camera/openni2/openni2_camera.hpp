#pragma once
#include "drivers/camera/camera_backend.hpp"
namespace fb {
CameraBackend openni2_camera_backend();
}  // namespace fb
