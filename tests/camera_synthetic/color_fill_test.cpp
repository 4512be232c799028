// The synthetic colour image's hole fill: a disocclusion shows the far surface, a crack its own.
#include <gtest/gtest.h>

#include "sim/camera/color_fill.hpp"

namespace fb {
namespace {

struct Canvas {
  ColorImage color;
  Image<float> z;
  Image<std::uint8_t> mark;
  Canvas(int w, int h) {
    color.resize(w, h);
    z.resize(w, h);
    mark.resize(w, h);
  }
  void splat(int x, int y, Rgb8 c, float depth) {
    color.at(x, y) = c;
    z.at(x, y) = depth;
    mark.at(x, y) = 1;
  }
};

constexpr Rgb8 kFace{200, 150, 120};
constexpr Rgb8 kWall{40, 60, 80};

TEST(ColorFill, ADisocclusionShowsTheFarSideAndACrackItsOwnSurface) {
  // A near object on x < 20 (800 mm), the wall from x = 26 on (1500 mm): the 6 px between them
  // are a disocclusion. Row 5 is a crack no depth pixel landed on; x = 10 of row 3 another.
  Canvas c(40, 10);
  for (int y = 0; y < 10; ++y) {
    if (y == 5) continue;
    for (int x = 0; x < 40; ++x) {
      if (x >= 20 && x < 26) continue;
      if (y == 3 && x == 10) continue;
      x < 20 ? c.splat(x, y, kFace, 800.0f) : c.splat(x, y, kWall, 1500.0f);
    }
  }
  fill_color_holes(c.color, c.z, c.mark);
  for (int y = 0; y < 10; ++y)
    for (int x = 0; x < 40; ++x) {
      ASSERT_EQ(c.mark.at(x, y), 1) << x << "," << y;
      const Rgb8 want = x < 20 ? kFace : kWall;
      EXPECT_EQ(c.color.at(x, y).r, want.r) << x << "," << y;
      EXPECT_EQ(c.color.at(x, y).b, want.b) << x << "," << y;
    }
}

TEST(ColorFill, ACrackBetweenTwoShadesIsInterpolated) {
  Canvas c(5, 1);
  c.splat(0, 0, Rgb8{100, 100, 100}, 800.0f);
  c.splat(4, 0, Rgb8{140, 140, 140}, 801.0f);
  fill_color_holes(c.color, c.z, c.mark);
  EXPECT_EQ(c.color.at(2, 0).g, 120);
  EXPECT_NEAR(c.z.at(2, 0), 800.5f, 1e-3f);
}

}  // namespace
}  // namespace fb
