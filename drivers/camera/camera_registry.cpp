#include <string>

#include "drivers/camera/camera_backend.hpp"
#include "drivers/camera/camera_plugin.hpp"
#include "drivers/camera/common/camera_uri.hpp"

namespace fb {

namespace {

// The backend named in `uri`: built in, else a loadable module (camera_plugin.hpp).
Result<CameraBackend> find_backend(std::string_view uri, std::string& arguments) {
  auto parsed = parse_camera_uri(uri);
  if (!parsed) return parsed.failure();
  arguments = parsed->arguments;
  std::string known;
  for (const auto& backend : camera_backends()) {
    if (backend.name == parsed->backend) return backend;
    known += (known.empty() ? "" : ", ") + std::string(backend.name);
  }
  auto plugin = load_camera_plugin(parsed->backend);
  if (plugin) return plugin;
  return fail("unknown camera backend '" + parsed->backend + "' in '" + std::string(uri) +
              "'; this build has: " + known + "; as a module: " + plugin.error().message);
}

bool accepts(const CameraBackend& backend, std::string_view control) {
  std::string_view rest = backend.controls;
  while (!rest.empty()) {
    const auto comma = rest.find(',');
    if (rest.substr(0, comma) == control) return true;
    if (comma == std::string_view::npos) break;
    rest.remove_prefix(comma + 1);
  }
  return false;
}

}  // namespace

Result<std::unique_ptr<DepthCamera>> open_camera(std::string_view uri,
                                                 const CameraControls& controls,
                                                 const CameraResources& resources) {
  std::string arguments;
  auto backend = find_backend(uri, arguments);
  if (!backend) return backend.failure();
  if (controls.empty() && (resources.face_model == nullptr || !backend->open_with_controls))
    return backend->open(arguments);
  for (const auto& control : controls) {
    if (!accepts(*backend, control.name)) {
      return fail("camera backend '" + std::string(backend->name) + "' has no control '" +
                  control.name + "'" +
                  (backend->controls.empty() ? std::string(" (it has none)")
                                             : "; it has: " + std::string(backend->controls)));
    }
  }
  return backend->open_with_controls(arguments, controls, resources);
}

bool camera_has_control(std::string_view uri, std::string_view control) {
  std::string arguments;
  auto backend = find_backend(uri, arguments);
  return backend && accepts(*backend, control);
}

std::vector<std::string> built_camera_backends() {
  std::vector<std::string> names;
  for (const auto& backend : camera_backends()) names.emplace_back(backend.name);
  for (const auto& backend : camera_plugins()) names.emplace_back(backend.name);
  return names;
}

std::vector<CameraListing> list_cameras() {
  std::vector<CameraListing> all;
  auto backends = camera_backends();
  for (const auto& plugin : camera_plugins()) backends.push_back(plugin);
  for (const auto& backend : backends) {
    auto listed = backend.list();
    all.insert(all.end(), listed.begin(), listed.end());
  }
  return all;
}

}  // namespace fb
