// Backend-independent button and LED timing, kept pure (levels and times in, events out) so it
// is tested without hardware and shared by every backend that reads raw line levels.
#pragma once

#include <cstdint>
#include <optional>

#include "drivers/gpio/gpio.hpp"

namespace fb {

struct DebounceOptions {
  int debounce_ms = 30;      // a level must hold this long to count (contact bounce is < 10 ms)
  int long_press_ms = 1500;  // held this long = a long press, reported while still held
};

// Turns raw pressed/released levels of one button into short and long presses.
// A long press fires once when the hold time is reached (so the user gets feedback without
// releasing); its release then produces nothing. A short press fires on release.
class ButtonDebouncer {
 public:
  explicit ButtonDebouncer(DebounceOptions options = {}) : options_(options) {}

  // A raw level observed at t_ms (an edge event or a poll). Times must not decrease.
  void sample(bool pressed, std::int64_t t_ms);
  // Advances time to t_ms; returns a completed press, if one completed. Call it after every
  // sample and periodically (at least every few ms of the debounce time) while waiting.
  std::optional<PressKind> update(std::int64_t t_ms);

  bool pressed() const { return stable_; }

 private:
  DebounceOptions options_;
  bool raw_ = false;
  std::int64_t raw_since_ = 0;
  bool stable_ = false;
  std::int64_t pressed_at_ = 0;
  bool long_fired_ = false;
};

// The LED level of a pattern at time t_ms (any monotonic origin).
// ready: steady on; recording: 4 Hz blink; processing: 1 Hz blink; error: two short flashes
// every second; off: off.
bool led_level(LedPattern pattern, std::int64_t t_ms);

}  // namespace fb
