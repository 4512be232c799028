// algo/core/clock.hpp: the one steady-clock helper every timing figure goes through.
#include <gtest/gtest.h>

#include "algo/core/clock.hpp"

namespace fb {
namespace {

TEST(Clock, MillisecondsAndSecondsBetweenTimePoints) {
  const Clock::time_point a{};
  const Clock::time_point b = a + std::chrono::microseconds(1500);
  EXPECT_DOUBLE_EQ(ms_between(a, b), 1.5);
  EXPECT_DOUBLE_EQ(ms_between(b, a), -1.5);
  // A start in the past gives a positive, finite duration (no timing threshold asserted).
  const auto start = Clock::now() - std::chrono::seconds(2);
  const double ms = ms_since(start);
  EXPECT_GE(ms, 2000.0);
  EXPECT_GE(seconds_since(start), 2.0);
  EXPECT_LT(seconds_since(start), 1e6);
}

}  // namespace
}  // namespace fb
