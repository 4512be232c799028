// Row-major images with owned storage. Resizing to the same size never reallocates,
// so frames can be reused in steady state without allocation.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace fb {

template <class Pixel>
struct Image {
  int width = 0;
  int height = 0;
  std::vector<Pixel> pixels;

  void resize(int w, int h) {
    width = w;
    height = h;
    pixels.resize(static_cast<std::size_t>(w) * static_cast<std::size_t>(h));
  }
  bool empty() const { return pixels.empty(); }
  Pixel& at(int x, int y) { return pixels[static_cast<std::size_t>(y) * width + x]; }
  const Pixel& at(int x, int y) const { return pixels[static_cast<std::size_t>(y) * width + x]; }
  bool contains(int x, int y) const { return x >= 0 && y >= 0 && x < width && y < height; }
};

struct Rgb8 {
  std::uint8_t r = 0;
  std::uint8_t g = 0;
  std::uint8_t b = 0;
};

using DepthImage = Image<std::uint16_t>;      // millimetres, 0 = no measurement
using DisparityImage = Image<std::uint16_t>;  // Kinect v1 raw 11-bit values, 2047 = no measurement
using ColorImage = Image<Rgb8>;

inline constexpr std::uint16_t kInvalidDisparity = 2047;

}  // namespace fb
