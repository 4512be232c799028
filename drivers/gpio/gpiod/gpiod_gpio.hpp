// The `gpiod` GPIO backend: libgpiod 1.6 (Debian bookworm, v1 C++ bindings gpiod.hpp).
// Buttons are requested for both edges with the chip's pull-up and active-low flags; every edge
// is re-read as a logical level and fed to ButtonDebouncer. The status LED is an output line
// animated by led_level() while the caller waits for events.
#pragma once

#include "drivers/gpio/gpio_backend.hpp"

namespace fb {

GpioBackend gpiod_gpio_backend();

}  // namespace fb
