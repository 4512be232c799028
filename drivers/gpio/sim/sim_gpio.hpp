// The `sim` GPIO backend: buttons pressed by software (tests, the HTTP API's
// /api/sim/button, the headless session) and an LED whose pattern history is recorded so tests
// can check what the state machine showed.
#pragma once

#include <condition_variable>
#include <deque>
#include <mutex>

#include "drivers/gpio/gpio_backend.hpp"

namespace fb {

class SimGpio : public Gpio, public ButtonSimulator {
 public:
  explicit SimGpio(const GpioOptions& options);

  const GpioInfo& info() const override { return info_; }
  Result<std::vector<ButtonEvent>> wait_events(std::chrono::milliseconds timeout) override;
  void set_pattern(LedPattern pattern) override;
  LedPattern pattern() const override;
  bool led_on() const override;
  Result<void> simulate_press(const ButtonEvent& event) override;

  // Every distinct pattern set so far, in order (consecutive repeats collapsed).
  std::vector<LedPattern> pattern_history() const;

 private:
  GpioInfo info_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<ButtonEvent> queue_;
  LedPattern pattern_ = LedPattern::kOff;
  std::vector<LedPattern> history_;
};

GpioBackend sim_gpio_backend();

}  // namespace fb
