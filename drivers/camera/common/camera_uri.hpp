// Camera URIs: `backend:arguments`, where arguments are either a path (`replay:DIR`) or a
// comma-separated key=value list (`synthetic:seed=3,expr=jawOpen`).
#pragma once

#include <map>
#include <string>
#include <string_view>
#include <utility>

#include "algo/core/result.hpp"

namespace fb {

struct CameraUri {
  std::string backend;    // text before the first ':'
  std::string arguments;  // everything after it, verbatim
};

// Splits `backend:arguments`; a URI without ':' is a backend with no arguments.
Result<CameraUri> parse_camera_uri(std::string_view uri);

// Parses `k1=v1,k2=v2`. Keys must be unique and non-empty; a bare `key` means `key=1`.
Result<std::map<std::string, std::string>> parse_key_values(std::string_view arguments);

// Options of a recorded take, the same for every backend that plays one (`replay:DIR,...`,
// `openni2:FILE.oni,...`).
struct RecordingOptions {
  bool realtime = false;  // pace frames at the recorded times (else as fast as they are read)
  bool loop = false;      // start over at the end instead of reporting kEndOfStream
  // Fault injection (replay only; -1 = off): after this many frames since start() the stream
  // stalls (next_frame() times out from then on) or fails, as an unplugged sensor does.
  long long stall_after = -1;
  long long fail_after = -1;
};
inline constexpr std::string_view kRecordingOptionsHelp =
    "realtime=0|1, loop=0|1, stall_after=N, fail_after=N";

// Splits `PATH[,realtime=0|1][,loop=0|1]`. A comma starts the options only if everything after
// it is a valid option list, so paths containing commas still work. An unknown option is an
// error naming the accepted ones; `backend` names the URI's kind in errors ("replay").
Result<std::pair<std::string, RecordingOptions>> split_recording_options(std::string_view arguments,
                                                                         std::string_view backend);

}  // namespace fb
