#include "drivers/gpio/button_logic.hpp"

namespace fb {

void ButtonDebouncer::sample(bool pressed, std::int64_t t_ms) {
  if (pressed != raw_) {
    raw_ = pressed;
    raw_since_ = t_ms;
  }
}

std::optional<PressKind> ButtonDebouncer::update(std::int64_t t_ms) {
  if (raw_ != stable_ && t_ms - raw_since_ >= options_.debounce_ms) {
    stable_ = raw_;
    if (stable_) {
      pressed_at_ = raw_since_;
      long_fired_ = false;
    } else if (!long_fired_) {
      return PressKind::kShort;
    }
  }
  if (stable_ && !long_fired_ && t_ms - pressed_at_ >= options_.long_press_ms) {
    long_fired_ = true;
    return PressKind::kLong;
  }
  return std::nullopt;
}

bool led_level(LedPattern pattern, std::int64_t t_ms) {
  const std::int64_t t = t_ms < 0 ? 0 : t_ms;
  switch (pattern) {
    case LedPattern::kOff:
      return false;
    case LedPattern::kReady:
      return true;
    case LedPattern::kRecording:
      return (t % 250) < 125;
    case LedPattern::kProcessing:
      return (t % 1000) < 500;
    case LedPattern::kError: {
      const std::int64_t phase = t % 1000;
      return phase < 100 || (phase >= 200 && phase < 300);
    }
    case LedPattern::kCalibrate: {
      const std::int64_t phase = t % 2000;
      return phase < 500 && (phase % 200) < 100;
    }
  }
  return false;
}

}  // namespace fb
