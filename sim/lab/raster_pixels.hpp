// The lab's pictures drawn with the project's rasterizer (eval texture's avatar, render
// transfer's meshes): each pixel a triangle covers, with the barycentric weights of its corners,
// and a per-vertex attribute interpolated there.
#pragma once

#include <array>
#include <cstdint>
#include <span>

#include <Eigen/Core>

#include "algo/render/rasterizer.hpp"

namespace fb::cli {

struct RasterPixel {
  int x = 0, y = 0;
  std::size_t triangle = 0;
  std::array<float, 3> bary{};  // weights of the triangle's three corners
};

// Calls f(RasterPixel) for every covered pixel of `raster`, row by row.
template <typename F>
void for_each_covered_pixel(const RasterBuffers& raster, F&& f) {
  for (int y = 0; y < raster.height; ++y) {
    for (int x = 0; x < raster.width; ++x) {
      const std::size_t i = raster.index(x, y);
      if (raster.triangle[i] == kNoTriangle) continue;
      f(RasterPixel{x,
                    y,
                    static_cast<std::size_t>(raster.triangle[i]),
                    {1.0f - raster.bary1[i] - raster.bary2[i], raster.bary1[i], raster.bary2[i]}});
    }
  }
}

// A 3-float-per-vertex attribute (normals, positions) interpolated at a covered pixel.
inline Eigen::Vector3f interpolate(std::span<const float> attribute,
                                   std::span<const std::uint32_t> triangles, const RasterPixel& p) {
  Eigen::Vector3f out = Eigen::Vector3f::Zero();
  for (int c = 0; c < 3; ++c)
    out += p.bary[c] *
           Eigen::Vector3f(attribute.data() + 3 * std::size_t{triangles[3 * p.triangle + c]});
  return out;
}

}  // namespace fb::cli
