// The one interface every GPIO backend implements: the kiosk's push buttons (debounced, short
// and long presses) and its status LED (blink patterns driven by the session state machine).
// Like DepthCamera, a backend owns its handles and callers own the Gpio through unique_ptr.
#pragma once

#include <chrono>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "algo/core/result.hpp"

namespace fb {

// Logical buttons of the box. kMain starts a session / says "ready" / retries; a long press on
// kMain cancels. kMode switches between capture and tracking mode.
enum class ButtonId { kMain, kMode };
enum class PressKind { kShort, kLong };

struct ButtonEvent {
  ButtonId button = ButtonId::kMain;
  PressKind kind = PressKind::kShort;
};

// What the status LED shows. The state machine picks one; the backend animates it.
// kCalibrate: the camera's depth-to-colour registration is off (faceboothd refuses to fit
// until it is calibrated); three short flashes every 2 s, unlike kError's two per second.
enum class LedPattern { kOff, kReady, kRecording, kProcessing, kError, kCalibrate };

const char* to_string(ButtonId button);
const char* to_string(PressKind kind);
const char* to_string(LedPattern pattern);
std::optional<ButtonId> parse_button(std::string_view name);
std::optional<LedPattern> parse_led_pattern(std::string_view name);

// Everything a backend may need; each backend reads its part. Mirrors [gpio] in the config.
struct GpioOptions {
  std::string backend = "sim";     // "sim" or "gpiod" (when built)
  std::string chip = "gpiochip0";  // gpiod: chip name, path or number
  int main_line = 17;              // gpiod: line offsets (BCM numbering on a Raspberry Pi)
  int mode_line = 27;
  int led_line = 22;               // -1 = no LED
  bool buttons_active_low = true;  // buttons pull the line to ground (internal pull-up)
  int debounce_ms = 30;
  int long_press_ms = 1500;
};

struct GpioInfo {
  std::string backend;
  std::string description;
};

class Gpio {
 public:
  virtual ~Gpio() = default;
  Gpio(const Gpio&) = delete;
  Gpio& operator=(const Gpio&) = delete;

  virtual const GpioInfo& info() const = 0;

  // Waits up to `timeout` for button presses and returns the completed ones (possibly none).
  // Backends that animate an LED do so while waiting, so the caller keeps calling this in a loop.
  virtual Result<std::vector<ButtonEvent>> wait_events(std::chrono::milliseconds timeout) = 0;

  virtual void set_pattern(LedPattern pattern) = 0;
  virtual LedPattern pattern() const = 0;
  // The LED's level right now (the pattern at this instant).
  virtual bool led_on() const = 0;

 protected:
  Gpio() = default;
};

// What a backend without real buttons offers besides Gpio (the `sim` backend): presses injected
// as if a person had pressed the button. The daemon's /api/sim/button, its headless session and
// the tests reach it through simulate_press(), never through Gpio.
class ButtonSimulator {
 public:
  virtual ~ButtonSimulator() = default;
  virtual Result<void> simulate_press(const ButtonEvent& event) = 0;
};

// Injects `event` when `gpio` is a ButtonSimulator; fails for a backend with real buttons.
Result<void> simulate_press(Gpio& gpio, const ButtonEvent& event);

// Opens the backend named by options.backend. Only built backends are accepted; the error lists
// those that are.
Result<std::unique_ptr<Gpio>> open_gpio(const GpioOptions& options);
std::vector<std::string> built_gpio_backends();

}  // namespace fb
