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
// With a rig whose captures have wrinkle detail (issue 40 item 5) the object ends with
// "detail_weights":{"smile@1":0.9981,"jaw_open@2":-0.0012}: the frame's map weights, one per
// captured expression with detail maps, keyed EXPRESSION@CAPTURE (4 decimals; they may leave
// [0, 1]). The frame's detail is E = N + sum_e c_e (D_e - N) on the displacement and normal maps
// (docs/wrinkles.md); without detail captures the field is absent.
// Formatting reuses the caller's string (no allocation once it has grown to a frame's size).
#pragma once

#include <span>
#include <string>
#include <string_view>

#include "algo/tracking/arkit.hpp"

namespace fb {

// The frame's wrinkle map weights: weights[e] for keys[e] ("EXPRESSION@CAPTURE"; names made of
// letters, digits, _ and -: written without escaping).
struct LiveDetailWeights {
  std::span<const std::string> keys;
  std::span<const float> weights;
};

void format_frame_json(const ArkitFrame& frame, std::string& out,
                       const LiveDetailWeights& detail = {});
void format_sse_event(const ArkitFrame& frame, std::string& out, std::string_view event = "face",
                      const LiveDetailWeights& detail = {});

}  // namespace fb
