// Host time for frame stamps: the wall clock's reading when the clock is made, advanced by the
// monotonic clock. The values look like wall time (fakenect dumps name their files by it, and
// a recording made today says so), but they never jump when NTP or an operator sets the clock
// mid-stream: a tracked take's frame times, its Live Link timecode and the pose filter's time
// steps stay the sensor's 33 ms apart.
#pragma once

#include <chrono>

namespace fb {

class HostClock {
 public:
  HostClock()
      : wall0_s_(std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch())
                     .count()),
        mono0_(std::chrono::steady_clock::now()) {}

  double now_s() const {
    return wall0_s_ +
           std::chrono::duration<double>(std::chrono::steady_clock::now() - mono0_).count();
  }

 private:
  double wall0_s_;
  std::chrono::steady_clock::time_point mono0_;
};

}  // namespace fb
