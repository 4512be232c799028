// What the daemon's HTTP API reads from a request: JSON bodies, the ids in paths, the rig
// upload's names= query value. Parsed and checked here, apart from the server (http_api.cpp),
// so tests and the fuzz target (tests/fuzz/http_requests_fuzz.cpp) reach them without one.
// Every error is a message for the client (the handler answers 400 or 422 with it).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "algo/core/result.hpp"
#include "storage/stored_data.hpp"

namespace fb {

// A correction from the kiosk: landmark `index` dragged to `u, v` (colour image px).
struct ColorCorrection {
  int index = 0;
  double u = 0, v = 0;
};

// An id from a route's (\d{1,12}) group: digits only, no sign, at most 12 of them.
Result<std::int64_t> parse_path_id(std::string_view digits);

// POST .../captures/I/landmarks: {"corrections": [{"index": 0..67, "u": px, "v": px}, ...]},
// 1..68 entries.
Result<std::vector<ColorCorrection>> parse_landmark_corrections(std::string_view body);
// POST /api/session/start|next|retry|cancel: empty, {} or {"subject": "name"} (<= 120 bytes).
// Gives the subject name ("" when none).
Result<std::string> parse_control_request(std::string_view body);
// POST /api/mode: {"mode": "tracking"|"capture"}. Gives true for tracking.
Result<bool> parse_mode_request(std::string_view body);
// POST /api/camera/self-calibrate: empty, {} or {"frames": 10..300}.
Result<int> parse_self_calibrate_request(std::string_view body, int default_frames);

struct ButtonRequest {
  std::string button = "main";  // "main" or "mode"
  bool long_press = false;
};
// POST /api/sim/button: {"button": "main"|"mode", "kind": "short"|"long"} (both optional).
Result<ButtonRequest> parse_button_request(std::string_view body);

// The rig upload's names= value: comma-separated, empty names and names over 64 bytes dropped.
std::vector<std::string> parse_shape_names_param(std::string_view names);
// Checks a decoded shape.bs against the face model (`vertex_count` vertices) and names its
// shapes: from `names` (the query value) when given, else the model's expression names in
// order ("shapeK" past them).
Result<void> check_rig_upload(RigData& rig, int vertex_count,
                              const std::optional<std::string>& names,
                              const std::vector<std::string>& model_expression_names);

// The rig upload's detail= value (issue 40 item 5): the captures of the session whose wrinkle
// detail the host built, "CAPTURE:EXPRESSION" comma-separated ("1:smile,2:jaw_open"), at most
// 64, each index listed once. Only the syntax: the handler checks them against the session and
// the guide.
Result<std::vector<RigDetailCapture>> parse_rig_detail_param(std::string_view detail);

}  // namespace fb
