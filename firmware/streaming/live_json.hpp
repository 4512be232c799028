// The kiosk page's live stream: one tracked frame as a JSON object, and as a Server-Sent Events
// event (`event: face`, `id: <frame>`, `data: <json>`, blank line). The daemon's HTTP server
// writes these strings to its `text/event-stream` clients; nothing here does I/O.
//
// JSON: {"frame":N,"t":s,"face":true|false,"occluded":true|false,"hidden":0.42,
//        "head":{"yaw":deg,"pitch":deg,"roll":deg,"x":mm,"y":mm,"z":mm},
//        "weights":{"eyeBlinkLeft":0.123,...}}  (ARKit's 52 names, 3 decimals; head angles as in
// Live Link Face but in degrees; x, y, z = the model origin in the depth camera frame;
// "hidden" = the share of the face something in front of it hides, "occluded" when that is
// over the tracker's threshold).
// Formatting reuses the caller's string (no allocation once it has grown to a frame's size).
#pragma once

#include <string>
#include <string_view>

#include "algo/tracking/arkit.hpp"

namespace fb {

void format_frame_json(const ArkitFrame& frame, std::string& out);
void format_sse_event(const ArkitFrame& frame, std::string& out, std::string_view event = "face");

}  // namespace fb
