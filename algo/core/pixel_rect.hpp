// The one pixel rectangle type: half-open [x0, x1) x [y0, y1), in whichever image its user
// names (depth or colour).
#pragma once

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
};

// No limit: every pixel of any image.
inline constexpr PixelRect kAllPixels{0, 0, 1 << 30, 1 << 30};

}  // namespace fb
