// The one pixel rectangle type: half-open [x0, x1) x [y0, y1), in whichever image its user
// names (depth or colour).
#pragma once

#include <algorithm>

namespace fb {

struct PixelRect {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;

  static constexpr PixelRect from_size(int x, int y, int width, int height) {
    return {x, y, x + width, y + height};
  }
  constexpr int width() const { return x1 - x0; }
  constexpr int height() const { return y1 - y0; }
  constexpr bool empty() const { return x1 <= x0 || y1 <= y0; }
  constexpr bool contains(int x, int y) const { return x >= x0 && y >= y0 && x < x1 && y < y1; }
  friend constexpr bool operator==(const PixelRect&, const PixelRect&) = default;

  // The same rectangle clipped to a w x h image (empty, with x1 >= x0 and y1 >= y0, when they
  // do not overlap).
  constexpr PixelRect clipped(int w, int h) const {
    const int cx0 = std::clamp(x0, 0, w), cy0 = std::clamp(y0, 0, h);
    return {cx0, cy0, std::max(cx0, std::clamp(x1, 0, w)), std::max(cy0, std::clamp(y1, 0, h))};
  }
  // Grown by `n` pixels on every side.
  constexpr PixelRect grown(int n) const { return {x0 - n, y0 - n, x1 + n, y1 + n}; }
  // The rectangle on a pyramid level that is 2^level times smaller (rounded outwards).
  constexpr PixelRect at_level(int level) const {
    const int round_up = (1 << level) - 1;
    return {x0 >> level, y0 >> level, (x1 + round_up) >> level, (y1 + round_up) >> level};
  }
};

// No limit: every pixel of any image.
inline constexpr PixelRect kAllPixels{0, 0, 1 << 30, 1 << 30};

}  // namespace fb
