#include <gtest/gtest.h>

#include <filesystem>
#include <thread>

#include "drivers/gpio/button_logic.hpp"
#include "drivers/gpio/gpio.hpp"
#include "drivers/gpio/sim/sim_gpio.hpp"

namespace fb {
namespace {

// Feeds a sequence of (t, level) samples, advancing time in 1 ms steps, and collects presses.
std::vector<PressKind> run(ButtonDebouncer& d, const std::vector<std::pair<int, bool>>& samples,
                           int end_ms) {
  std::vector<PressKind> out;
  std::size_t next = 0;
  for (int t = 0; t <= end_ms; ++t) {
    while (next < samples.size() && samples[next].first == t) {
      d.sample(samples[next].second, t);
      ++next;
    }
    if (auto k = d.update(t)) out.push_back(*k);
  }
  return out;
}

TEST(ButtonDebouncer, BouncyShortPressIsOnePress) {
  ButtonDebouncer d({30, 1500});
  // Contact bounce on press and release, 200 ms hold.
  auto presses = run(d,
                     {{10, true},
                      {11, false},
                      {12, true},
                      {14, false},
                      {15, true},  // bounce in
                      {215, false},
                      {216, true},
                      {218, false}},  // bounce out
                     600);
  ASSERT_EQ(presses.size(), 1u);
  EXPECT_EQ(presses[0], PressKind::kShort);
  EXPECT_FALSE(d.pressed());
}

TEST(ButtonDebouncer, GlitchShorterThanDebounceIsIgnored) {
  ButtonDebouncer d({30, 1500});
  auto presses = run(d, {{100, true}, {120, false}, {300, true}, {305, false}}, 1000);
  EXPECT_TRUE(presses.empty());
}

TEST(ButtonDebouncer, LongPressFiresWhileHeldAndReleaseAddsNothing) {
  ButtonDebouncer d({30, 1500});
  std::vector<PressKind> presses;
  d.sample(true, 0);
  for (int t = 0; t <= 1600; ++t)
    if (auto k = d.update(t)) presses.push_back(*k);
  ASSERT_EQ(presses.size(), 1u);  // reported before release
  EXPECT_EQ(presses[0], PressKind::kLong);
  d.sample(false, 2000);
  for (int t = 2000; t <= 2100; ++t)
    if (auto k = d.update(t)) presses.push_back(*k);
  EXPECT_EQ(presses.size(), 1u);
}

TEST(ButtonDebouncer, TwoPressesInARow) {
  ButtonDebouncer d({20, 1000});
  auto presses = run(
      d, {{0, true}, {100, false}, {200, true}, {1300, false}, {1400, true}, {1450, false}}, 1600);
  EXPECT_EQ(presses,
            (std::vector<PressKind>{PressKind::kShort, PressKind::kLong, PressKind::kShort}));
}

TEST(LedPatterns, ShapesPerPattern) {
  auto on_ms = [](LedPattern p) {
    int on = 0;
    for (int t = 0; t < 1000; ++t) on += led_level(p, t) ? 1 : 0;
    return on;
  };
  EXPECT_EQ(on_ms(LedPattern::kOff), 0);
  EXPECT_EQ(on_ms(LedPattern::kReady), 1000);
  EXPECT_EQ(on_ms(LedPattern::kRecording), 500);   // 4 Hz, 50 %
  EXPECT_EQ(on_ms(LedPattern::kProcessing), 500);  // 1 Hz, 50 %
  EXPECT_EQ(on_ms(LedPattern::kError), 200);       // two 100 ms flashes
  EXPECT_EQ(on_ms(LedPattern::kCalibrate), 300);   // three 100 ms flashes (every 2 s)
  // Recording blinks faster than processing: count rising edges in one second.
  auto edges = [](LedPattern p) {
    int n = 0;
    for (int t = 1; t < 1000; ++t) n += (led_level(p, t) && !led_level(p, t - 1)) ? 1 : 0;
    return n;
  };
  EXPECT_EQ(edges(LedPattern::kRecording), 3);  // + the one at t = 0
  EXPECT_EQ(edges(LedPattern::kError), 1);
  EXPECT_EQ(edges(LedPattern::kCalibrate), 2);
}

TEST(GpioNames, RoundTrip) {
  for (auto p : {LedPattern::kOff, LedPattern::kReady, LedPattern::kRecording,
                 LedPattern::kProcessing, LedPattern::kError, LedPattern::kCalibrate}) {
    EXPECT_EQ(parse_led_pattern(to_string(p)), p);
  }
  EXPECT_EQ(parse_button("main"), ButtonId::kMain);
  EXPECT_EQ(parse_button("mode"), ButtonId::kMode);
  EXPECT_FALSE(parse_button("../etc").has_value());
}

TEST(SimGpio, PressesArriveInOrderAcrossThreads) {
  auto gpio = open_gpio({});
  ASSERT_TRUE(gpio) << gpio.error().message;
  EXPECT_EQ((*gpio)->info().backend, "sim");
  std::thread presser([&] {
    ASSERT_TRUE(simulate_press(**gpio, {ButtonId::kMain, PressKind::kShort}));
    ASSERT_TRUE(simulate_press(**gpio, {ButtonId::kMode, PressKind::kLong}));
  });
  std::vector<ButtonEvent> got;
  while (got.size() < 2) {
    auto events = (*gpio)->wait_events(std::chrono::milliseconds(5000));
    ASSERT_TRUE(events);
    got.insert(got.end(), events->begin(), events->end());
  }
  presser.join();
  EXPECT_EQ(got[0].button, ButtonId::kMain);
  EXPECT_EQ(got[0].kind, PressKind::kShort);
  EXPECT_EQ(got[1].button, ButtonId::kMode);
  EXPECT_EQ(got[1].kind, PressKind::kLong);
  // Nothing pending: a zero wait returns no events.
  auto none = (*gpio)->wait_events(std::chrono::milliseconds(0));
  ASSERT_TRUE(none);
  EXPECT_TRUE(none->empty());
}

TEST(SimGpio, RecordsPatternHistory) {
  SimGpio gpio({});
  gpio.set_pattern(LedPattern::kReady);
  gpio.set_pattern(LedPattern::kReady);
  gpio.set_pattern(LedPattern::kRecording);
  gpio.set_pattern(LedPattern::kProcessing);
  EXPECT_EQ(gpio.pattern(), LedPattern::kProcessing);
  EXPECT_EQ(gpio.pattern_history(),
            (std::vector<LedPattern>{LedPattern::kReady, LedPattern::kRecording,
                                     LedPattern::kProcessing}));
  gpio.set_pattern(LedPattern::kReady);
  EXPECT_TRUE(gpio.led_on());
}

TEST(GpioRegistry, UnknownBackendListsBuiltOnes) {
  GpioOptions options;
  options.backend = "nonsense";
  auto gpio = open_gpio(options);
  ASSERT_FALSE(gpio);
  EXPECT_NE(gpio.error().message.find("sim"), std::string::npos) << gpio.error().message;
}

#ifdef FB_WITH_GPIOD
TEST(GpiodGpio, MissingChipIsAClearError) {
  // There is no gpio-sim/gpio-mockup module on the build machines: a chip that does not exist
  // must give an actionable message, not an exception or a crash.
  GpioOptions options;
  options.backend = "gpiod";
  options.chip = "gpiochip-facebooth-missing";
  auto gpio = open_gpio(options);
  ASSERT_FALSE(gpio);
  EXPECT_NE(gpio.error().message.find("gpiochip-facebooth-missing"), std::string::npos);
  EXPECT_NE(gpio.error().message.find("udev"), std::string::npos) << gpio.error().message;
}

TEST(GpiodGpio, RealChipWhenPresent) {
  if (!std::filesystem::exists("/dev/gpiochip0")) GTEST_SKIP() << "no /dev/gpiochip0 here";
  GpioOptions options;
  options.backend = "gpiod";
  auto gpio = open_gpio(options);
  if (!gpio) GTEST_SKIP() << gpio.error().message;
  EXPECT_FALSE(simulate_press(**gpio, {}).ok());
  auto events = (*gpio)->wait_events(std::chrono::milliseconds(20));
  EXPECT_TRUE(events);
}
#endif

}  // namespace
}  // namespace fb
