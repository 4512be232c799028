// Figures in the daemon's status JSON and messages about the camera's registration: never NaN
// or infinite (the kiosk page would print "nan"); a missing one reads 0.
#pragma once

#include <cmath>
#include <cstdio>
#include <string>

namespace fb {

inline double finite_or_zero(double v) {
  return std::isfinite(v) ? v : 0.0;
}

inline std::string fixed_or_zero(double v, int digits = 1) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.*f", digits, finite_or_zero(v));
  return buf;
}

}  // namespace fb
