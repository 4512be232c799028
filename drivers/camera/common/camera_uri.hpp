// Camera URIs: `backend:arguments`, where arguments are either a path (`replay:DIR`) or a
// comma-separated key=value list (`synthetic:seed=3,expr=jawOpen`).
#pragma once

#include <map>
#include <string>
#include <string_view>

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

}  // namespace fb
