#include "drivers/camera/common/camera_uri.hpp"

namespace fb {

Result<CameraUri> parse_camera_uri(std::string_view uri) {
  if (uri.empty()) {
    return fail("empty camera URI; use e.g. 'synthetic:', 'replay:DIR', 'freenect:0' or 'openni2:FILE.oni'");
  }
  const auto colon = uri.find(':');
  CameraUri parsed;
  parsed.backend = std::string(uri.substr(0, colon));
  if (colon != std::string_view::npos) parsed.arguments = std::string(uri.substr(colon + 1));
  if (parsed.backend.empty()) {
    return fail("camera URI '" + std::string(uri) + "' has no backend name before ':'");
  }
  return parsed;
}

Result<std::map<std::string, std::string>> parse_key_values(std::string_view arguments) {
  std::map<std::string, std::string> values;
  std::size_t start = 0;
  while (start <= arguments.size() && !arguments.empty()) {
    const auto comma = arguments.find(',', start);
    const auto item = arguments.substr(start, comma == std::string_view::npos ? std::string_view::npos
                                                                               : comma - start);
    if (!item.empty()) {
      const auto eq = item.find('=');
      std::string key(item.substr(0, eq));
      std::string value = eq == std::string_view::npos ? "1" : std::string(item.substr(eq + 1));
      if (key.empty()) return fail("camera option '" + std::string(item) + "' has no name before '='");
      if (values.count(key)) return fail("camera option '" + key + "' is given twice");
      values.emplace(std::move(key), std::move(value));
    }
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
  return values;
}

}  // namespace fb
