// A figure as text for people: fixed digits, or "n/a" when it is missing (NaN or infinite: a
// fit that did not run, a mean over nothing), so "nan" never reaches a user. JSON writers put
// null there instead.
#pragma once

#include <cmath>
#include <cstdio>
#include <string>

#include <nlohmann/json.hpp>

namespace fb {

inline std::string figure_text(double v, int digits = 2) {
  if (!std::isfinite(v)) return "n/a";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

// The same figure for JSON: null when missing (nlohmann keeps a NaN in memory and only the
// dump turns it into null; readers of the in-process JSON must see null too).
inline nlohmann::json figure_json(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
}

}  // namespace fb
