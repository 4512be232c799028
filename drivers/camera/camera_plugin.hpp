// Camera backends as loadable modules, the way libcamera loads its IPA modules and GStreamer its
// plugins: the product binaries link only the backends in drivers/; a backend they do not know,
// `NAME:...`, is looked up as the module `fb_camera_NAME.so` in the plugin directories and
// loaded with dlopen. The laboratory's synthetic camera is such a module (sim/camera), so
// faceboothd runs the demo on it without linking anything from sim/.
//
// Directories, in order: $FACEBOOTH_CAMERA_PLUGINS (colon-separated), the build tree's
// camera-plugins/ (when it exists), the installed lib/facebooth/cameras. A module stays loaded
// for the life of the process (RTLD_NODELETE): the cameras it made may outlive the handle.
#pragma once

#include <filesystem>
#include <string_view>
#include <vector>

#include "drivers/camera/camera_backend.hpp"

namespace fb {

// Bumped whenever CameraBackend, DepthCamera or the frame types change layout; a module built
// against another version is refused with a message saying to rebuild it.
inline constexpr int kCameraPluginAbi = 1;

struct CameraPlugin {
  int abi = kCameraPluginAbi;
  CameraBackend backend;
};

// Every module exports this, with C linkage: `extern "C" const fb::CameraPlugin*
// fb_camera_plugin();`
inline constexpr const char* kCameraPluginEntry = "fb_camera_plugin";
using CameraPluginEntry = const CameraPlugin* (*)();

// The directories searched, in order (existing ones only).
std::vector<std::filesystem::path> camera_plugin_directories();

// Loads the module of backend `name`; fails when none is found or it cannot be loaded.
Result<CameraBackend> load_camera_plugin(std::string_view name);

// Every loadable module's backend (modules that fail to load are skipped).
std::vector<CameraBackend> camera_plugins();

}  // namespace fb
