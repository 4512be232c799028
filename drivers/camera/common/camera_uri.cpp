#include "drivers/camera/common/camera_uri.hpp"

#include <charconv>
#include <filesystem>
#include <optional>

namespace fb {

Result<CameraUri> parse_camera_uri(std::string_view uri) {
  if (uri.empty()) {
    return fail(
        "empty camera URI; use e.g. 'synthetic:', 'replay:DIR', 'freenect:0' or "
        "'openni2:FILE.oni'");
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
    const auto item = arguments.substr(
        start, comma == std::string_view::npos ? std::string_view::npos : comma - start);
    if (!item.empty()) {
      const auto eq = item.find('=');
      std::string key(item.substr(0, eq));
      std::string value = eq == std::string_view::npos ? "1" : std::string(item.substr(eq + 1));
      if (key.empty())
        return fail("camera option '" + std::string(item) + "' has no name before '='");
      if (values.count(key)) return fail("camera option '" + key + "' is given twice");
      values.emplace(std::move(key), std::move(value));
    }
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
  return values;
}

namespace {

Result<RecordingOptions> parse_recording_options(std::string_view text, std::string_view backend) {
  auto values = parse_key_values(text);
  if (!values) return values.failure();
  RecordingOptions options;
  for (const auto& [key, value] : *values) {
    if (key == "stall_after" || key == "fail_after") {
      long long n = -1;
      const auto [end, ec] = std::from_chars(value.data(), value.data() + value.size(), n);
      if (ec != std::errc{} || end != value.data() + value.size() || n < 0)
        return fail(std::string(backend) + " option '" + key + "=" + value +
                    "' must be a frame count (0 or more)");
      (key == "stall_after" ? options.stall_after : options.fail_after) = n;
      continue;
    }
    bool* target = key == "realtime" ? &options.realtime : key == "loop" ? &options.loop : nullptr;
    if (target == nullptr) {
      return fail("unknown " + std::string(backend) + " option '" + key +
                  "'; the accepted ones are " + std::string(kRecordingOptionsHelp));
    }
    if (value == "1" || value == "true" || value == "yes") {
      *target = true;
    } else if (value == "0" || value == "false" || value == "no") {
      *target = false;
    } else {
      return fail(std::string(backend) + " option '" + key + "=" + value + "' must be 0 or 1");
    }
  }
  return options;
}

}  // namespace

Result<std::pair<std::string, RecordingOptions>> split_recording_options(std::string_view arguments,
                                                                         std::string_view backend) {
  std::optional<Error> option_error;
  for (std::size_t comma = arguments.find(','); comma != std::string_view::npos;
       comma = arguments.find(',', comma + 1)) {
    auto options = parse_recording_options(arguments.substr(comma + 1), backend);
    if (options) return std::pair{std::string(arguments.substr(0, comma)), *options};
    if (!option_error) option_error = options.error();
  }
  // No option list found. If the whole thing is not a file or directory but a suffix looked
  // like options, report the option error: it is the likelier mistake.
  std::error_code ec;
  if (option_error && !std::filesystem::exists(std::string(arguments), ec))
    return fail(option_error->message);
  return std::pair{std::string(arguments), RecordingOptions{}};
}

}  // namespace fb
