// Notices the wall clock being set (NTP stepping it after a booth without a battery-backed
// clock boots, an operator fixing the time): the difference between the wall clock and the
// monotonic clock changes. The daemon's timeouts, pacing and frame times follow the monotonic
// clock and are not affected; the status and the log say that it happened, since the times the
// store records (created_at) follow the new clock from then on.
#pragma once

#include <chrono>
#include <optional>

namespace fb {

class WallClockWatch {
 public:
  static constexpr double kThresholdS = 2.0;  // NTP slews smaller errors; steps are larger
  WallClockWatch() : offset_s_(offset_now()) {}

  // The step in seconds since the last check (positive: set forward), when above the threshold.
  std::optional<double> check() {
    const double offset = offset_now();
    const double step = offset - offset_s_;
    offset_s_ = offset;
    if (step > kThresholdS || step < -kThresholdS) return step;
    return std::nullopt;
  }

 private:
  static double offset_now() {
    using namespace std::chrono;
    return duration<double>(system_clock::now().time_since_epoch()).count() -
           duration<double>(steady_clock::now().time_since_epoch()).count();
  }
  double offset_s_;
};

}  // namespace fb
