#include "algo/texture/texel_map.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace fb {

Result<TexelMap> make_texel_map(std::span<const float> uvs,
                                std::span<const std::uint32_t> triangle_uvs, int width,
                                int height) {
  if (std::min(width, height) < 16 || std::max(width, height) > 8192)
    return fail("texture size " + std::to_string(width) + "x" + std::to_string(height) +
                " is outside 16..8192; pick e.g. 1024");
  if (uvs.empty() || triangle_uvs.size() % 3 != 0 || triangle_uvs.empty())
    return fail("the mesh has no UV layout (the face model asset carries one; reconvert it)");
  const std::size_t uv_count = uvs.size() / 2;
  TexelMap map;
  map.width = width;
  map.height = height;
  const std::size_t n = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
  map.triangle.assign(n, -1);
  map.bary.assign(n, Eigen::Vector3f::Zero());
  const auto sx = static_cast<float>(width), sy = static_cast<float>(height);
  // Texels within kMargin texels outside every triangle (the rim of each chart) show the
  // nearest triangle's nearest point, so that filtering across a chart's border (and across a
  // UV seam, whose two sides are one surface) reads surface colour, not the gutter.
  constexpr float kMargin = 1.5f;
  std::vector<float> distance(n, std::numeric_limits<float>::infinity());
  for (int pass = 0; pass < 2; ++pass) {  // interiors first, then the rims
    const float margin = pass == 0 ? 0.0f : kMargin;
    for (std::size_t t = 0; t < triangle_uvs.size() / 3; ++t) {
      Eigen::Vector2f p[3];
      for (int k = 0; k < 3; ++k) {
        const std::uint32_t i = triangle_uvs[3 * t + k];
        if (i >= uv_count) return fail("UV index out of range in the mesh's UV layout");
        // Texel space: x = u * width - 0.5, y = (1 - v) * height - 0.5 (centres at integers).
        p[k] = {uvs[2 * i] * sx - 0.5f, (1.0f - uvs[2 * i + 1]) * sy - 0.5f};
      }
      const float area =
          (p[1] - p[0]).x() * (p[2] - p[0]).y() - (p[1] - p[0]).y() * (p[2] - p[0]).x();
      if (std::abs(area) < 1e-12f) continue;
      // Heights over each edge turn a negative barycentric weight into a distance in texels.
      const float edge_height[3] = {std::abs(area) / std::max(1e-6f, (p[2] - p[1]).norm()),
                               std::abs(area) / std::max(1e-6f, (p[0] - p[2]).norm()),
                               std::abs(area) / std::max(1e-6f, (p[1] - p[0]).norm())};
      const auto lo = [&](float a, float b, float c) {
        return std::max(0, static_cast<int>(std::ceil(std::min({a, b, c}) - margin)));
      };
      const auto hi = [&](float a, float b, float c, int side) {
        return std::min(side - 1, static_cast<int>(std::floor(std::max({a, b, c}) + margin)));
      };
      const int x0 = lo(p[0].x(), p[1].x(), p[2].x());
      const int x1 = hi(p[0].x(), p[1].x(), p[2].x(), width);
      const int y0 = lo(p[0].y(), p[1].y(), p[2].y());
      const int y1 = hi(p[0].y(), p[1].y(), p[2].y(), height);
      for (int y = y0; y <= y1; ++y) {
        for (int x = x0; x <= x1; ++x) {
          const Eigen::Vector2f q(static_cast<float>(x), static_cast<float>(y));
          auto edge = [&](const Eigen::Vector2f& a, const Eigen::Vector2f& b) {
            return ((b - a).x() * (q - a).y() - (b - a).y() * (q - a).x()) / area;
          };
          Eigen::Vector3f w(edge(p[1], p[2]), edge(p[2], p[0]), edge(p[0], p[1]));
          float outside = 0.0f;  // texels outside the triangle
          for (int k = 0; k < 3; ++k) outside = std::max(outside, -w[k] * edge_height[k]);
          const std::size_t i = map.index(x, y);
          if (pass == 0) {
            if (outside > 1e-5f) continue;
            if (map.triangle[i] < 0) ++map.covered;
            distance[i] = 0.0f;
          } else {
            if (outside > kMargin || outside >= distance[i]) continue;
            w = w.cwiseMax(0.0f);
            w /= w.sum();
            if (map.triangle[i] < 0) ++map.rim;
            distance[i] = outside;
          }
          map.triangle[i] = static_cast<std::int32_t>(t);
          map.bary[i] = w;
        }
      }
    }
  }
  if (map.covered == 0)
    return fail("the UV layout covers no texel of a " + std::to_string(width) + "x" +
                std::to_string(height) + " atlas");
  return map;
}

}  // namespace fb
