#include "algo/texture/atlas_fill.hpp"

#include <algorithm>
#include <vector>

namespace fb {

namespace {

struct Level {
  Image<Eigen::Vector3f> sum;  // colour times weight
  Image<float> weight;
};

Eigen::Vector3f average(const Level& l, int x, int y) {
  const float w = l.weight.at(x, y);
  return w > 0.0f ? Eigen::Vector3f(l.sum.at(x, y) / w) : Eigen::Vector3f::Zero();
}

// Bilinear sample of a level's average colour at fine texel (x, y) of a level twice the size.
Eigen::Vector3f upsample(const Level& coarse, int x, int y) {
  const float fx = std::clamp((x + 0.5f) / 2.0f - 0.5f, 0.0f, coarse.sum.width - 1.0f);
  const float fy = std::clamp((y + 0.5f) / 2.0f - 0.5f, 0.0f, coarse.sum.height - 1.0f);
  const int x0 = static_cast<int>(fx), y0 = static_cast<int>(fy);
  const int x1 = std::min(x0 + 1, coarse.sum.width - 1),
            y1 = std::min(y0 + 1, coarse.sum.height - 1);
  const float ax = fx - x0, ay = fy - y0;
  return (1 - ay) * ((1 - ax) * average(coarse, x0, y0) + ax * average(coarse, x1, y0)) +
         ay * ((1 - ax) * average(coarse, x0, y1) + ax * average(coarse, x1, y1));
}

}  // namespace

void push_pull_fill(Image<Eigen::Vector3f>& color, const Image<float>& known) {
  std::vector<Level> levels(1);
  levels[0].sum.resize(color.width, color.height);
  levels[0].weight.resize(color.width, color.height);
  for (std::size_t i = 0; i < color.pixels.size(); ++i) {
    const float w = known.pixels[i] > 0.0f ? 1.0f : 0.0f;
    levels[0].weight.pixels[i] = w;
    levels[0].sum.pixels[i] = w * color.pixels[i];
  }
  // Push: halve until one texel, summing colour and weight (weights saturate at 1 per texel).
  while (levels.back().sum.width > 1 || levels.back().sum.height > 1) {
    const Level& f = levels.back();
    Level c;
    const int w = std::max(1, (f.sum.width + 1) / 2), h = std::max(1, (f.sum.height + 1) / 2);
    c.sum.resize(w, h);
    c.weight.resize(w, h);
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        Eigen::Vector3f s = Eigen::Vector3f::Zero();
        float ws = 0.0f;
        for (int dy = 0; dy < 2; ++dy)
          for (int dx = 0; dx < 2; ++dx)
            if (f.sum.contains(2 * x + dx, 2 * y + dy)) {
              s += f.sum.at(2 * x + dx, 2 * y + dy);
              ws += f.weight.at(2 * x + dx, 2 * y + dy);
            }
        const float scale = ws > 1.0f ? 1.0f / ws : 1.0f;
        c.sum.at(x, y) = s * scale;
        c.weight.at(x, y) = ws * scale;
      }
    }
    levels.push_back(std::move(c));
  }
  // Pull: from coarse to fine, a texel's missing weight is made up from the coarser level.
  for (std::size_t l = levels.size() - 1; l-- > 0;) {
    Level& f = levels[l];
    const Level& c = levels[l + 1];
    for (int y = 0; y < f.sum.height; ++y) {
      for (int x = 0; x < f.sum.width; ++x) {
        const float w = f.weight.at(x, y);
        if (w >= 1.0f) continue;
        const Eigen::Vector3f mean =
            w > 0.0f ? Eigen::Vector3f(f.sum.at(x, y) / w) : Eigen::Vector3f::Zero();
        const Eigen::Vector3f filled = w * mean + (1.0f - w) * upsample(c, x, y);
        f.sum.at(x, y) = filled;
        f.weight.at(x, y) = 1.0f;
      }
    }
  }
  for (std::size_t i = 0; i < color.pixels.size(); ++i)
    if (!(known.pixels[i] > 0.0f)) color.pixels[i] = levels[0].sum.pixels[i];
}

void mesh_fill(Image<Eigen::Vector3f>& color, Image<float>& known, const TexelMap& map,
               std::span<const std::uint32_t> triangles, std::size_t vertex_count) {
  std::vector<Eigen::Vector3f> sum(vertex_count, Eigen::Vector3f::Zero());
  std::vector<float> weight(vertex_count, 0.0f);
  for (std::size_t i = 0; i < map.triangle.size(); ++i) {
    if (map.triangle[i] < 0 || !(known.pixels[i] > 0.0f)) continue;
    const auto t = static_cast<std::size_t>(map.triangle[i]);
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t v = triangles[3 * t + k];
      sum[v] += map.bary[i][k] * color.pixels[i];
      weight[v] += map.bary[i][k];
    }
  }
  // A vertex is seen when observed texels carry a fair share of it (not one texel's corner).
  constexpr float kSeen = 0.5f;
  std::vector<Eigen::Vector3f> vertex(vertex_count, Eigen::Vector3f::Zero());
  std::vector<std::uint8_t> done(vertex_count, 0);
  std::vector<std::uint32_t> frontier;
  for (std::size_t v = 0; v < vertex_count; ++v)
    if (weight[v] >= kSeen) {
      vertex[v] = sum[v] / weight[v];
      done[v] = 1;
    }
  // Neighbours along triangle edges (CSR).
  std::vector<std::uint32_t> start(vertex_count + 1, 0), adjacent;
  for (std::size_t t = 0; t + 2 < triangles.size(); t += 3)
    for (int k = 0; k < 3; ++k) start[triangles[t + k] + 1] += 2;
  for (std::size_t v = 0; v < vertex_count; ++v) start[v + 1] += start[v];
  adjacent.resize(start.back());
  std::vector<std::uint32_t> fill = start;
  for (std::size_t t = 0; t + 2 < triangles.size(); t += 3)
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t v = triangles[t + k];
      adjacent[fill[v]++] = triangles[t + (k + 1) % 3];
      adjacent[fill[v]++] = triangles[t + (k + 2) % 3];
    }
  for (bool changed = true; changed;) {  // breadth first: one ring of unseen vertices per pass
    changed = false;
    std::vector<std::pair<std::uint32_t, Eigen::Vector3f>> ring;
    for (std::uint32_t v = 0; v < vertex_count; ++v) {
      if (done[v]) continue;
      Eigen::Vector3f s = Eigen::Vector3f::Zero();
      int n = 0;
      for (std::uint32_t e = start[v]; e < start[v + 1]; ++e)
        if (done[adjacent[e]] == 1) {
          s += vertex[adjacent[e]];
          ++n;
        }
      if (n > 0) ring.emplace_back(v, s / static_cast<float>(n));
    }
    for (const auto& [v, c] : ring) {
      vertex[v] = c;
      done[v] = 1;
      changed = true;
    }
  }
  for (std::size_t i = 0; i < map.triangle.size(); ++i) {
    if (map.triangle[i] < 0 || known.pixels[i] > 0.0f) continue;
    const auto t = static_cast<std::size_t>(map.triangle[i]);
    Eigen::Vector3f c = Eigen::Vector3f::Zero();
    for (int k = 0; k < 3; ++k) c += map.bary[i][k] * vertex[triangles[3 * t + k]];
    color.pixels[i] = c;
    known.pixels[i] = 1.0f;
  }
}

}  // namespace fb
