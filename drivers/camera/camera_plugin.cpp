#include "drivers/camera/camera_plugin.hpp"

#include <dlfcn.h>

#include <cstdlib>
#include <memory>
#include <string>
#include <system_error>

namespace fb {
namespace {

// Closes the handle when done; the module's code stays mapped (RTLD_NODELETE) for the cameras
// it made.
struct ModuleCloser {
  void operator()(void* handle) const {
    if (handle != nullptr) dlclose(handle);
  }
};
using ModuleHandle = std::unique_ptr<void, ModuleCloser>;

std::string module_file(std::string_view name) {
  return "fb_camera_" + std::string(name) + ".so";
}

Result<CameraBackend> load_module(const std::filesystem::path& path) {
  ModuleHandle handle(dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL | RTLD_NODELETE));
  if (!handle) {
    const char* why = dlerror();
    return fail("cannot load the camera module " + path.string() + ": " +
                (why != nullptr ? why : "unknown error") + "; rebuild or reinstall it");
  }
  auto entry = reinterpret_cast<CameraPluginEntry>(dlsym(handle.get(), kCameraPluginEntry));
  if (entry == nullptr) {
    return fail("the camera module " + path.string() + " has no " + kCameraPluginEntry +
                "(); it is not a facebooth camera module");
  }
  const CameraPlugin* plugin = entry();
  if (plugin == nullptr || plugin->abi != kCameraPluginAbi) {
    return fail("the camera module " + path.string() + " was built for camera ABI " +
                std::to_string(plugin != nullptr ? plugin->abi : -1) + ", this build uses " +
                std::to_string(kCameraPluginAbi) + "; rebuild it with this source tree");
  }
  return plugin->backend;
}

}  // namespace

std::vector<std::filesystem::path> camera_plugin_directories() {
  std::vector<std::filesystem::path> candidates;
  if (const char* env = std::getenv("FACEBOOTH_CAMERA_PLUGINS"); env != nullptr) {
    std::string_view rest = env;
    while (!rest.empty()) {
      const auto colon = rest.find(':');
      const auto part = rest.substr(0, colon);
      if (!part.empty()) candidates.emplace_back(part);
      if (colon == std::string_view::npos) break;
      rest.remove_prefix(colon + 1);
    }
  }
  candidates.emplace_back(FB_CAMERA_PLUGIN_BUILD_DIR);
  candidates.emplace_back(FB_CAMERA_PLUGIN_INSTALL_DIR);
  std::vector<std::filesystem::path> existing;
  for (const auto& dir : candidates) {
    std::error_code ec;
    if (std::filesystem::is_directory(dir, ec)) existing.push_back(dir);
  }
  return existing;
}

Result<CameraBackend> load_camera_plugin(std::string_view name) {
  const std::string file = module_file(name);
  std::string searched;
  for (const auto& dir : camera_plugin_directories()) {
    std::error_code ec;
    if (std::filesystem::exists(dir / file, ec)) return load_module(dir / file);
    searched += (searched.empty() ? "" : ", ") + dir.string();
  }
  return fail("no camera module " + file + " in " +
              (searched.empty() ? std::string("any plugin directory") : searched) +
              " (set FACEBOOTH_CAMERA_PLUGINS to the directory that has it)");
}

std::vector<CameraBackend> camera_plugins() {
  std::vector<CameraBackend> found;
  std::vector<std::string> seen;
  for (const auto& dir : camera_plugin_directories()) {
    std::error_code ec;
    for (const auto& entry : std::filesystem::directory_iterator(dir, ec)) {
      const std::string file = entry.path().filename().string();
      if (file.rfind("fb_camera_", 0) != 0 || entry.path().extension() != ".so") continue;
      bool duplicate = false;
      for (const auto& s : seen) duplicate = duplicate || s == file;
      if (duplicate) continue;  // an earlier directory wins
      seen.push_back(file);
      if (auto backend = load_module(entry.path())) found.push_back(*backend);
    }
  }
  return found;
}

}  // namespace fb
