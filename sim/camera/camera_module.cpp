// The synthetic camera as a loadable camera module (drivers/camera/camera_plugin.hpp): built as
// fb_camera_synthetic.so, so faceboothd and facebooth open `synthetic:` URIs without linking sim/.
#include "drivers/camera/camera_plugin.hpp"
#include "sim/camera/synthetic_camera.hpp"

extern "C" __attribute__((visibility("default"))) const fb::CameraPlugin* fb_camera_plugin() {
  static const fb::CameraPlugin plugin{fb::kCameraPluginAbi, fb::synthetic_camera_backend()};
  return &plugin;
}
