#include "firmware/daemon/http_requests.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <nlohmann/json.hpp>

namespace fb {
namespace {

using nlohmann::json;

// An object, or null for a body that is not one (empty counts as {}).
json parse_body(std::string_view body) {
  if (body.empty()) return json::object();
  json j = json::parse(body.begin(), body.end(), nullptr, false);
  return j.is_object() ? j : json(nullptr);
}

// The string member `key`, `fallback` when absent, nullopt when it is not a string.
std::optional<std::string> string_member(const json& body, const char* key,
                                         const std::string& fallback) {
  const auto it = body.find(key);
  if (it == body.end()) return fallback;
  if (!it->is_string()) return std::nullopt;
  return it->get<std::string>();
}

// An integer member within [lo, hi] (checked before narrowing, so 2^32 + 20 is not 20).
std::optional<int> int_member(const json& value, int lo, int hi) {
  if (value.is_number_unsigned()) {  // nlohmann keeps non-negative integers unsigned
    const auto v = value.get<std::uint64_t>();
    if (lo > 0 && v < static_cast<std::uint64_t>(lo)) return std::nullopt;
    if (v > static_cast<std::uint64_t>(hi)) return std::nullopt;
    return static_cast<int>(v);
  }
  if (!value.is_number_integer()) return std::nullopt;
  const auto v = value.get<std::int64_t>();
  if (v < lo || v > hi) return std::nullopt;
  return static_cast<int>(v);
}

}  // namespace

Result<std::int64_t> parse_path_id(std::string_view digits) {
  std::int64_t id = 0;
  const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), id);
  if (digits.empty() || digits.size() > 12 || digits.front() == '-' || ec != std::errc() ||
      end != digits.data() + digits.size())
    return fail("bad id '" + std::string(digits.substr(0, 24)) + "': expected 1..12 digits");
  return id;
}

Result<std::vector<ColorCorrection>> parse_landmark_corrections(std::string_view text) {
  const json body = parse_body(text);
  const std::string shape =
      "body must be {\"corrections\": [{\"index\": 0..67, \"u\": px, \"v\": px}, ...]} with "
      "1..68 entries";
  if (body.is_null() || !body.contains("corrections")) return fail(shape);
  const json& list = body["corrections"];
  if (!list.is_array() || list.empty() || list.size() > 68) return fail(shape);
  std::vector<ColorCorrection> out;
  for (const auto& c : list) {
    if (!c.is_object() || !c.contains("index") || !c.contains("u") || !c["u"].is_number() ||
        !c.contains("v") || !c["v"].is_number())
      return fail("each correction needs an integer index 0..67 and numbers u, v");
    const auto index = int_member(c["index"], 0, 67);
    if (!index) return fail("each correction's index must be an integer in 0..67");
    out.push_back({*index, c["u"].get<double>(), c["v"].get<double>()});
  }
  return out;
}

Result<std::string> parse_control_request(std::string_view text) {
  const json body = parse_body(text);
  if (body.is_null()) return fail("body must be a JSON object");
  auto subject = string_member(body, "subject", "");
  if (!subject) return fail("subject must be a string (the subject's name)");
  if (subject->size() > 120) return fail("subject name too long (at most 120 bytes)");
  return *subject;
}

Result<bool> parse_mode_request(std::string_view text) {
  const json body = parse_body(text);
  const auto mode = body.is_object() ? string_member(body, "mode", "") : std::nullopt;
  if (!mode || (*mode != "tracking" && *mode != "capture"))
    return fail("body must be {\"mode\": \"tracking\"|\"capture\"}");
  return *mode == "tracking";
}

Result<int> parse_self_calibrate_request(std::string_view text, int default_frames) {
  const json body = parse_body(text);
  if (body.is_null()) return fail("body must be a JSON object (or empty)");
  if (!body.contains("frames")) return default_frames;
  const auto frames = int_member(body["frames"], 10, 300);
  if (!frames)
    return fail("frames must be an integer in 10..300 (default " + std::to_string(default_frames) +
                ")");
  return *frames;
}

Result<ButtonRequest> parse_button_request(std::string_view text) {
  const json body = parse_body(text);
  if (body.is_null()) return fail("body must be a JSON object");
  const auto button = string_member(body, "button", "main");
  if (!button || (*button != "main" && *button != "mode"))
    return fail("button must be \"main\" or \"mode\"");
  const auto kind = string_member(body, "kind", "short");
  if (!kind || (*kind != "short" && *kind != "long"))
    return fail("kind must be \"short\" or \"long\"");
  return ButtonRequest{*button, *kind == "long"};
}

std::vector<std::string> parse_shape_names_param(std::string_view names) {
  std::vector<std::string> out;
  std::size_t start = 0;
  while (start <= names.size()) {
    const auto comma = std::min(names.find(',', start), names.size());
    const auto name = names.substr(start, comma - start);
    if (!name.empty() && name.size() <= 64) out.emplace_back(name);
    start = comma + 1;
  }
  return out;
}

Result<void> check_rig_upload(RigData& rig, int vertex_count,
                              const std::optional<std::string>& names,
                              const std::vector<std::string>& model_expression_names) {
  if (rig.vertex_count() != vertex_count)
    return fail("the rig has " + std::to_string(rig.vertex_count()) +
                " vertices; the face model has " + std::to_string(vertex_count));
  if (rig.shape_count() < 1 || rig.shape_count() > 256)
    return fail("a rig needs 1..256 blendshapes");
  auto sane = [](const std::vector<float>& v) {
    return std::all_of(v.begin(), v.end(),
                       [](float x) { return std::isfinite(x) && std::abs(x) < 2000.f; });
  };
  if (!sane(rig.neutral) || !std::all_of(rig.shapes.begin(), rig.shapes.end(), sane))
    return fail("the rig has non-finite or out-of-range coordinates");
  rig.shape_names.clear();
  if (names) {
    rig.shape_names = parse_shape_names_param(*names);
    if (static_cast<int>(rig.shape_names.size()) != rig.shape_count())
      return fail("names= lists " + std::to_string(rig.shape_names.size()) + " names for " +
                  std::to_string(rig.shape_count()) + " shapes");
    return success();
  }
  for (int k = 0; k < rig.shape_count(); ++k) {
    const auto i = static_cast<std::size_t>(k);
    rig.shape_names.push_back(i < model_expression_names.size() ? model_expression_names[i]
                                                                : "shape" + std::to_string(k));
  }
  return success();
}

Result<std::vector<RigDetailCapture>> parse_rig_detail_param(std::string_view detail) {
  constexpr const char* kForm =
      " (detail= lists the captures with wrinkle detail as CAPTURE:EXPRESSION, comma-separated, "
      "e.g. detail=1:smile,2:jaw_open)";
  std::vector<RigDetailCapture> out;
  if (detail.empty()) return out;
  std::size_t start = 0;
  while (start <= detail.size()) {
    const auto comma = std::min(detail.find(',', start), detail.size());
    const auto item = detail.substr(start, comma - start);
    start = comma + 1;
    const auto colon = item.find(':');
    const auto digits = item.substr(0, colon);
    if (colon == std::string_view::npos || digits.empty() || digits.size() > 4 ||
        !std::all_of(digits.begin(), digits.end(), [](char c) { return c >= '0' && c <= '9'; }))
      return fail("detail= entry '" + std::string(item.substr(0, 80)) +
                  "' is not CAPTURE:EXPRESSION" + kForm);
    const auto expression = item.substr(colon + 1);
    if (expression.empty() || expression.size() > 64 ||
        !std::all_of(expression.begin(), expression.end(), [](char c) {
          return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-';
        }))
      return fail("detail= entry '" + std::string(item.substr(0, 80)) +
                  "' has no usable expression name (letters, digits, _ and -, 1..64)" + kForm);
    RigDetailCapture c{std::stoi(std::string(digits)), std::string(expression)};
    for (const auto& seen : out)
      if (seen.capture_index == c.capture_index)
        return fail("detail= lists capture " + std::to_string(c.capture_index) +
                    " twice; list each capture with wrinkle detail once");
    out.push_back(std::move(c));
    if (out.size() > 64) return fail("detail= lists more than 64 captures");
  }
  return out;
}

}  // namespace fb
