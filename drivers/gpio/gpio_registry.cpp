#include <string>

#include "drivers/gpio/gpio_backend.hpp"

namespace fb {

const char* to_string(ButtonId button) {
  switch (button) {
    case ButtonId::kMain:
      return "main";
    case ButtonId::kMode:
      return "mode";
  }
  return "?";
}

const char* to_string(PressKind kind) {
  return kind == PressKind::kLong ? "long" : "short";
}

const char* to_string(LedPattern pattern) {
  switch (pattern) {
    case LedPattern::kOff:
      return "off";
    case LedPattern::kReady:
      return "ready";
    case LedPattern::kRecording:
      return "recording";
    case LedPattern::kProcessing:
      return "processing";
    case LedPattern::kError:
      return "error";
    case LedPattern::kCalibrate:
      return "calibrate";
  }
  return "?";
}

std::optional<ButtonId> parse_button(std::string_view name) {
  if (name == "main") return ButtonId::kMain;
  if (name == "mode") return ButtonId::kMode;
  return std::nullopt;
}

std::optional<LedPattern> parse_led_pattern(std::string_view name) {
  for (auto p : {LedPattern::kOff, LedPattern::kReady, LedPattern::kRecording,
                 LedPattern::kProcessing, LedPattern::kError, LedPattern::kCalibrate}) {
    if (name == to_string(p)) return p;
  }
  return std::nullopt;
}

Result<std::unique_ptr<Gpio>> open_gpio(const GpioOptions& options) {
  std::string known;
  for (const auto& backend : gpio_backends()) {
    if (backend.name == options.backend) return backend.open(options);
    known += (known.empty() ? "" : ", ") + std::string(backend.name);
  }
  return fail(
      "unknown GPIO backend '" + options.backend + "'; this build has: " + known +
      (options.backend == "gpiod" ? " (configure with -DFB_WITH_GPIOD=ON and libgpiod-dev)" : ""));
}

std::vector<std::string> built_gpio_backends() {
  std::vector<std::string> names;
  for (const auto& backend : gpio_backends()) names.emplace_back(backend.name);
  return names;
}

Result<void> simulate_press(Gpio& gpio, const ButtonEvent& event) {
  if (auto* simulator = dynamic_cast<ButtonSimulator*>(&gpio))
    return simulator->simulate_press(event);
  return fail("GPIO backend '" + gpio.info().backend +
              "' has real buttons; it cannot simulate presses");
}

}  // namespace fb
