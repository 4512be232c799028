// What faceboothd reads from HTTP requests (firmware/daemon/http_requests), without a server:
// the JSON bodies, the ids in paths, a rig upload (shape.bs body + names= query value). Query
// strings and paths themselves are split and decoded by cpp-httplib (Debian's compiled library,
// not instrumented here); the project's handling of the values it hands over is fuzzed.
// The first byte picks the request, the rest is its body.
#include <cstring>

#include "firmware/daemon/http_requests.hpp"
#include "storage/export/facewarehouse.hpp"
#include "tests/fuzz/fuzz_util.hpp"

namespace {

// A rig upload: u16 (little-endian) length n of the names= value (0xFFFF: no names=), the
// value, then the shape.bs body, checked against a 4-vertex model with two expressions.
void rig_upload(std::string_view input) {
  if (input.size() < 2) return;
  std::uint16_t n = 0;
  std::memcpy(&n, input.data(), 2);
  input.remove_prefix(2);
  std::optional<std::string> names;
  if (n != 0xFFFF) {
    if (n > input.size()) return;
    names = std::string(input.substr(0, n));
    input.remove_prefix(n);
  }
  auto rig = fb::decode_shape_bs(std::span<const std::uint8_t>(
      reinterpret_cast<const std::uint8_t*>(input.data()), input.size()));
  if (!rig) return;
  if (fb::check_rig_upload(*rig, 4, names, {"jawOpen", "mouthSmile_L"}))
    fb::fuzz::require(static_cast<int>(rig->shape_names.size()) == rig->shape_count(),
                      "an accepted rig has one name per shape");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const std::string_view body = fb::fuzz::text(data + 1, size - 1);
  switch (data[0] % 8) {
    case 0: {
      auto corrections = fb::parse_landmark_corrections(body);
      if (corrections) {
        for (const auto& c : *corrections)
          fb::fuzz::require(c.index >= 0 && c.index < 68, "correction index in 0..67");
      }
      break;
    }
    case 1: {
      auto subject = fb::parse_control_request(body);
      if (subject) fb::fuzz::require(subject->size() <= 120, "subject name <= 120 bytes");
      break;
    }
    case 2:
      (void)fb::parse_mode_request(body);
      break;
    case 3: {
      auto frames = fb::parse_self_calibrate_request(body, 45);
      if (frames) fb::fuzz::require(*frames >= 10 && *frames <= 300, "frames in 10..300");
      break;
    }
    case 4:
      (void)fb::parse_button_request(body);
      break;
    case 5:
      (void)fb::parse_path_id(body);
      break;
    case 6:
      for (const auto& name : fb::parse_shape_names_param(body))
        fb::fuzz::require(!name.empty() && name.size() <= 64, "names are 1..64 bytes");
      break;
    default:
      rig_upload(body);
      break;
  }
  return 0;
}
