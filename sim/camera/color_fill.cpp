#include "sim/camera/color_fill.hpp"

#include <algorithm>
#include <cstddef>

namespace fb {
namespace {

// Two splatted ends belong to one surface when their depths agree within this band.
bool same_surface(float a, float b) {
  return std::abs(a - b) <= std::max(20.0f, 0.03f * a);
}

Rgb8 mix(Rgb8 a, Rgb8 b, float t) {
  auto lerp = [t](std::uint8_t u, std::uint8_t v) {
    return static_cast<std::uint8_t>(u + t * (static_cast<float>(v) - u) + 0.5f);
  };
  return {lerp(a.r, b.r), lerp(a.g, b.g), lerp(a.b, b.b)};
}

// One line of pixels (a row or a column), `n` long with `step` between neighbours. With
// `cracks_only`, only runs of at most kCrack pixels between two ends on one surface are filled.
constexpr int kCrack = 3;
void fill_line(Rgb8* color, float* z, std::uint8_t* mark, int n, std::ptrdiff_t step,
               bool cracks_only) {
  int previous = -1;  // last splatted index
  int i = 0;
  while (i < n) {
    if (mark[i * step] == 1) {
      previous = i++;
      continue;
    }
    int next = i;
    while (next < n && mark[next * step] != 1) ++next;
    const bool has_left = previous >= 0, has_right = next < n;
    const bool crack = has_left && has_right && next - i <= kCrack &&
                       same_surface(z[previous * step], z[next * step]);
    if ((has_left || has_right) && (crack || !cracks_only)) {
      const std::ptrdiff_t l = previous * step, r = next * step;
      for (int k = i; k < next; ++k) {
        const std::ptrdiff_t j = k * step;
        if (has_left && has_right && same_surface(z[l], z[r])) {
          const float t = static_cast<float>(k - previous) / static_cast<float>(next - previous);
          color[j] = mix(color[l], color[r], t);
          z[j] = z[l] + t * (z[r] - z[l]);
        } else {
          // A disocclusion (or the image border): the farther side shows through.
          const bool use_left = !has_right || (has_left && z[l] > z[r]);
          color[j] = color[use_left ? l : r];
          z[j] = z[use_left ? l : r];
        }
        mark[j] = 2;
      }
    }
    i = next;
  }
}

}  // namespace

void fill_color_holes(ColorImage& color, Image<float>& z, Image<std::uint8_t>& mark) {
  const int w = color.width, h = color.height;
  auto rows = [&](bool cracks_only) {
    for (int y = 0; y < h; ++y) {
      const std::size_t row = static_cast<std::size_t>(y) * w;
      fill_line(&color.pixels[row], &z.pixels[row], &mark.pixels[row], w, 1, cracks_only);
    }
    for (auto& m : mark.pixels) m = m == 2 ? 1 : m;
  };
  auto columns = [&](bool cracks_only) {
    for (int x = 0; x < w; ++x)
      fill_line(&color.pixels[x], &z.pixels[x], &mark.pixels[x], h, w, cracks_only);
    for (auto& m : mark.pixels) m = m == 2 ? 1 : m;
  };
  // Cracks first (rows the mapping skipped, then gaps within a row), so that the disocclusion
  // pass along the rows (the parallax direction) sees whole surfaces at its run ends.
  columns(true);
  rows(true);
  rows(false);
  columns(false);
}

}  // namespace fb
