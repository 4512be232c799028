#include "firmware/streaming/live_json.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <numbers>

namespace fb {
namespace {

void append_fixed(std::string& out, double value, int decimals) {
  if (!std::isfinite(value)) value = 0.0;
  char buffer[48];
  const auto [end, ec] =
      std::to_chars(buffer, buffer + sizeof(buffer), value, std::chars_format::fixed, decimals);
  out.append(buffer, ec == std::errc() ? end : buffer);
}

void append_int(std::string& out, unsigned long long value) {
  char buffer[24];
  const auto [end, ec] = std::to_chars(buffer, buffer + sizeof(buffer), value);
  out.append(buffer, end);
}

void append_frame_json(const ArkitFrame& frame, const LiveDetailWeights& detail, std::string& out) {
  constexpr double kDeg = 180.0 / std::numbers::pi;
  const HeadAngles a = head_angles(head_rotation(frame.camera_from_model));
  const Eigen::Vector3d& t = frame.camera_from_model.translation;
  out += "{\"frame\":";
  append_int(out, frame.index);
  out += ",\"t\":";
  append_fixed(out, frame.time_s, 4);
  out += frame.face_found ? ",\"face\":true" : ",\"face\":false";
  out += frame.occluded ? ",\"occluded\":true,\"hidden\":" : ",\"occluded\":false,\"hidden\":";
  append_fixed(out, frame.occluded_fraction, 2);
  out += ",\"head\":{\"yaw\":";
  append_fixed(out, a.yaw * kDeg, 2);
  out += ",\"pitch\":";
  append_fixed(out, a.pitch * kDeg, 2);
  out += ",\"roll\":";
  append_fixed(out, a.roll * kDeg, 2);
  out += ",\"x\":";
  append_fixed(out, t.x(), 1);
  out += ",\"y\":";
  append_fixed(out, t.y(), 1);
  out += ",\"z\":";
  append_fixed(out, t.z(), 1);
  out += "},\"weights\":{";
  for (int i = 0; i < kArkitShapeCount; ++i) {
    if (i) out += ',';
    out += '"';
    out += kArkitNames[i];
    out += "\":";
    append_fixed(out, frame.weights[static_cast<std::size_t>(i)], 3);
  }
  out += '}';
  const std::size_t n = std::min(detail.keys.size(), detail.weights.size());
  if (n > 0) {
    out += ",\"detail_weights\":{";
    for (std::size_t e = 0; e < n; ++e) {
      if (e) out += ',';
      out += '"';
      out += detail.keys[e];
      out += "\":";
      append_fixed(out, detail.weights[e], 4);
    }
    out += '}';
  }
  out += '}';
}

}  // namespace

void format_frame_json(const ArkitFrame& frame, std::string& out, const LiveDetailWeights& detail) {
  out.clear();
  append_frame_json(frame, detail, out);
}

void format_sse_event(const ArkitFrame& frame, std::string& out, std::string_view event,
                      const LiveDetailWeights& detail) {
  // SSE: fields end with '\n' and an empty line ends the event; the JSON has no newlines.
  out.clear();
  out += "event: ";
  out += event;
  out += "\nid: ";
  append_int(out, frame.index);
  out += "\ndata: ";
  append_frame_json(frame, detail, out);
  out += "\n\n";
}

}  // namespace fb
