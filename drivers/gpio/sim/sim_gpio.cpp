#include "drivers/gpio/sim/sim_gpio.hpp"

#include "drivers/gpio/button_logic.hpp"

namespace fb {

SimGpio::SimGpio(const GpioOptions&) {
  info_.backend = "sim";
  info_.description = "simulated buttons (main, mode) and status LED";
}

Result<std::vector<ButtonEvent>> SimGpio::wait_events(std::chrono::milliseconds timeout) {
  std::unique_lock lock(mutex_);
  cv_.wait_for(lock, timeout, [&] { return !queue_.empty(); });
  std::vector<ButtonEvent> events(queue_.begin(), queue_.end());
  queue_.clear();
  return events;
}

void SimGpio::set_pattern(LedPattern pattern) {
  std::lock_guard lock(mutex_);
  pattern_ = pattern;
  if (history_.empty() || history_.back() != pattern) history_.push_back(pattern);
}

LedPattern SimGpio::pattern() const {
  std::lock_guard lock(mutex_);
  return pattern_;
}

bool SimGpio::led_on() const {
  const auto now = std::chrono::duration_cast<std::chrono::milliseconds>(
      std::chrono::steady_clock::now().time_since_epoch());
  return led_level(pattern(), now.count());
}

Result<void> SimGpio::simulate_press(const ButtonEvent& event) {
  {
    std::lock_guard lock(mutex_);
    queue_.push_back(event);
  }
  cv_.notify_all();
  return success();
}

std::vector<LedPattern> SimGpio::pattern_history() const {
  std::lock_guard lock(mutex_);
  return history_;
}

namespace {
Result<std::unique_ptr<Gpio>> open_sim(const GpioOptions& options) {
  return std::unique_ptr<Gpio>(std::make_unique<SimGpio>(options));
}
}  // namespace

GpioBackend sim_gpio_backend() {
  return {"sim", &open_sim, "sim  simulated buttons, pressed over the HTTP API or by tests"};
}

}  // namespace fb
