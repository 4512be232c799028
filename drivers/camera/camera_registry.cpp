#include <string>

#include "drivers/camera/camera_backend.hpp"
#include "drivers/camera/common/camera_uri.hpp"

namespace fb {

Result<std::unique_ptr<DepthCamera>> open_camera(std::string_view uri) {
  auto parsed = parse_camera_uri(uri);
  if (!parsed) return parsed.failure();
  std::string known;
  for (const auto& backend : camera_backends()) {
    if (backend.name == parsed->backend) return backend.open(parsed->arguments);
    known += (known.empty() ? "" : ", ") + std::string(backend.name);
  }
  return fail("unknown camera backend '" + parsed->backend + "' in '" + std::string(uri) +
              "'; this build has: " + known);
}

std::vector<std::string> built_camera_backends() {
  std::vector<std::string> names;
  for (const auto& backend : camera_backends()) names.emplace_back(backend.name);
  return names;
}

std::vector<CameraListing> list_cameras() {
  std::vector<CameraListing> all;
  for (const auto& backend : camera_backends()) {
    auto listed = backend.list();
    all.insert(all.end(), listed.begin(), listed.end());
  }
  return all;
}

}  // namespace fb
