#include "drivers/gpio/gpiod/gpiod_gpio.hpp"

#include <array>
#include <atomic>
#include <exception>
#include <gpiod.hpp>

#include "drivers/gpio/button_logic.hpp"

namespace fb {
namespace {

std::int64_t now_ms() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

class GpiodGpio : public Gpio {
 public:
  ~GpiodGpio() override {
    // gpiod::line objects release their request when the chip's last reference goes, but the
    // LED would keep its last level; switch it off first. Nothing may throw out of here.
    try {
      if (led_) led_.set_value(0);
      for (auto& line : buttons_)
        if (line) line.release();
      if (led_) led_.release();
    } catch (const std::exception&) {
    }
  }

  static Result<std::unique_ptr<Gpio>> open(const GpioOptions& options) {
    auto gpio = std::unique_ptr<GpiodGpio>(new GpiodGpio(options));
    try {
      gpio->chip_ = gpiod::chip(options.chip, gpiod::chip::OPEN_LOOKUP);
    } catch (const std::exception& e) {
      return fail("cannot open GPIO chip '" + options.chip + "': " + e.what() +
                  ". Check that /dev/" + options.chip +
                  " exists and that this user is in the group the udev rule gives it "
                  "(board/60-facebooth-gpio.rules: group gpio), or use [gpio] backend = \"sim\"");
    }
    const std::array<int, 2> offsets = {options.main_line, options.mode_line};
    try {
      std::bitset<32> flags = gpiod::line_request::FLAG_BIAS_PULL_UP;
      if (!options.buttons_active_low) flags = gpiod::line_request::FLAG_BIAS_PULL_DOWN;
      if (options.buttons_active_low) flags |= gpiod::line_request::FLAG_ACTIVE_LOW;
      for (std::size_t i = 0; i < offsets.size(); ++i) {
        if (offsets[i] < 0) continue;
        auto line = gpio->chip_.get_line(static_cast<unsigned>(offsets[i]));
        line.request({"faceboothd", gpiod::line_request::EVENT_BOTH_EDGES, flags});
        gpio->buttons_[i] = line;
      }
      if (options.led_line >= 0) {
        gpio->led_ = gpio->chip_.get_line(static_cast<unsigned>(options.led_line));
        gpio->led_.request({"faceboothd", gpiod::line_request::DIRECTION_OUTPUT, 0}, 0);
      }
    } catch (const std::exception& e) {
      return fail("cannot request GPIO lines on '" + options.chip + "' (main " +
                  std::to_string(options.main_line) + ", mode " +
                  std::to_string(options.mode_line) + ", led " + std::to_string(options.led_line) +
                  "): " + e.what() + ". Is another program using them (gpioinfo " + options.chip +
                  ")?");
    }
    return std::unique_ptr<Gpio>(std::move(gpio));
  }

  const GpioInfo& info() const override { return info_; }

  Result<std::vector<ButtonEvent>> wait_events(std::chrono::milliseconds timeout) override {
    std::vector<ButtonEvent> events;
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    try {
      // Slices of at most 10 ms: the LED animates and long presses fire while a button is held.
      while (true) {
        const auto left = deadline - std::chrono::steady_clock::now();
        const auto slice = std::min<std::chrono::nanoseconds>(
            std::max<std::chrono::nanoseconds>(left, std::chrono::nanoseconds(0)),
            std::chrono::milliseconds(10));
        bool any_edge = false;
        for (auto& line : buttons_) {
          if (!line) continue;
          if (line.event_wait(any_edge ? std::chrono::nanoseconds(0) : slice / 2)) {
            for (auto& e : line.event_read_multiple()) (void)e;  // drain; the level is re-read
            any_edge = true;
          }
        }
        const auto t = now_ms();
        for (std::size_t i = 0; i < buttons_.size(); ++i) {
          if (!buttons_[i]) continue;
          debouncers_[i].sample(buttons_[i].get_value() != 0, t);
          if (auto kind = debouncers_[i].update(t)) {
            events.push_back({i == 0 ? ButtonId::kMain : ButtonId::kMode, *kind});
          }
        }
        animate_led(t);
        if (!events.empty() || std::chrono::steady_clock::now() >= deadline) break;
      }
    } catch (const std::exception& e) {
      return fail(std::string("reading GPIO buttons failed: ") + e.what());
    }
    return events;
  }

  void set_pattern(LedPattern pattern) override {
    pattern_.store(pattern);
    animate_led(now_ms());
  }
  LedPattern pattern() const override { return pattern_.load(); }
  bool led_on() const override { return led_level(pattern_.load(), now_ms()); }

 private:
  explicit GpiodGpio(const GpioOptions& options) {
    info_.backend = "gpiod";
    info_.description = "libgpiod " + options.chip + ": main=" + std::to_string(options.main_line) +
                        " mode=" + std::to_string(options.mode_line) +
                        " led=" + std::to_string(options.led_line);
    const DebounceOptions d{options.debounce_ms, options.long_press_ms};
    debouncers_ = {ButtonDebouncer(d), ButtonDebouncer(d)};
  }

  void animate_led(std::int64_t t) {
    if (!led_) return;
    const int level = led_level(pattern_.load(), t) ? 1 : 0;
    if (level == led_written_) return;
    try {
      led_.set_value(level);
      led_written_ = level;
    } catch (const std::exception&) {
      // An LED that cannot be driven must not stop the buttons; the next change retries.
    }
  }

  GpioInfo info_;
  gpiod::chip chip_;
  std::array<gpiod::line, 2> buttons_;
  std::array<ButtonDebouncer, 2> debouncers_;
  gpiod::line led_;
  int led_written_ = -1;
  std::atomic<LedPattern> pattern_{LedPattern::kOff};
};

}  // namespace

GpioBackend gpiod_gpio_backend() {
  return {"gpiod", &GpiodGpio::open,
          "gpiod  libgpiod lines: [gpio] chip, main_line, mode_line, led_line"};
}

}  // namespace fb
