// The one clock for measured durations: a steady clock (never jumps with the wall clock) and
// milliseconds as double, as every figure and status field reports them. Reading a clock is
// not I/O, so algo/ may use it for its timing reports.
#pragma once

#include <chrono>

namespace fb {

using Clock = std::chrono::steady_clock;

inline double ms_between(Clock::time_point from, Clock::time_point to) {
  return std::chrono::duration<double, std::milli>(to - from).count();
}

inline double ms_since(Clock::time_point start) {
  return ms_between(start, Clock::now());
}

inline double seconds_since(Clock::time_point start) {
  return ms_since(start) / 1000.0;
}

}  // namespace fb
