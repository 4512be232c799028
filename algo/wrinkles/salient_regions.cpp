#include "algo/wrinkles/salient_regions.hpp"

#include <algorithm>
#include <cmath>

namespace fb {

namespace {

// A sign change of the gradient across (x, y) along (dx, dy), both sides over the threshold.
bool sign_change(const ImageGradient& g, int x, int y, int dx, int dy, float t) {
  const FloatImage& d = dx ? g.gx : g.gy;
  const float a = d.at(x - dx, y - dy), b = d.at(x + dx, y + dy);
  return (a < -t && b > t) || (a > t && b < -t);
}

// Minimum distance from p to the landmarks that mark the mouth, lips, brows and nose.
float feature_distance(const Eigen::Vector2d& p, const std::array<Eigen::Vector2d, 68>& l) {
  double best = 1e30;
  for (int i = 17; i < 68; ++i) {
    if (i >= 36 && i < 48) continue;  // the eyes: crow's feet and lids sit right beside them
    best = std::min(best, (l[static_cast<std::size_t>(i)] - p).norm());
  }
  return static_cast<float>(best);
}

PixelRectI merge(const PixelRectI& a, const PixelRectI& b) {
  const int x0 = std::min(a.x, b.x), y0 = std::min(a.y, b.y);
  const int x1 = std::max(a.x + a.width, b.x + b.width),
            y1 = std::max(a.y + a.height, b.y + b.height);
  return {x0, y0, x1 - x0, y1 - y0};
}

bool near(const PixelRectI& a, const PixelRectI& b, int gap) {
  return a.x - gap < b.x + b.width && b.x - gap < a.x + a.width && a.y - gap < b.y + b.height &&
         b.y - gap < a.y + a.height;
}

}  // namespace

SalientRegions salient_regions(const FloatImage& luminance,
                               const std::optional<std::array<Eigen::Vector2d, 68>>& landmarks,
                               const SalientOptions& o) {
  SalientRegions out;
  const int w = luminance.width, h = luminance.height;
  out.marked.resize(w, h);
  std::fill(out.marked.pixels.begin(), out.marked.pixels.end(), std::uint8_t{0});
  const ImageGradient g = image_gradient(luminance);
  for (int y = 2; y + 2 < h; ++y)
    for (int x = 2; x + 2 < w; ++x)
      if (sign_change(g, x, y, 1, 0, o.gradient_threshold) ||
          sign_change(g, x, y, 0, 1, o.gradient_threshold))
        out.marked.at(x, y) = 1;
  // Trace: 8-connected components of marked pixels.
  Image<std::uint8_t> seen = out.marked;
  std::vector<Eigen::Vector2i> stack;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      if (seen.at(x, y) != 1) continue;
      WrinkleLine line;
      stack.assign(1, {x, y});
      seen.at(x, y) = 2;
      int x0 = x, x1 = x, y0 = y, y1 = y;
      while (!stack.empty()) {
        const Eigen::Vector2i p = stack.back();
        stack.pop_back();
        line.pixels.push_back(p);
        x0 = std::min(x0, p.x()), x1 = std::max(x1, p.x()), y0 = std::min(y0, p.y()),
        y1 = std::max(y1, p.y());
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            const int qx = p.x() + dx, qy = p.y() + dy;
            if (seen.contains(qx, qy) && seen.at(qx, qy) == 1) {
              seen.at(qx, qy) = 2;
              stack.emplace_back(qx, qy);
            }
          }
      }
      line.box = {x0, y0, x1 - x0 + 1, y1 - y0 + 1};
      if (line.length() < o.min_line_px) continue;
      if (landmarks) {
        Eigen::Vector2d c = Eigen::Vector2d::Zero();
        for (const auto& p : line.pixels) c += p.cast<double>();
        c /= static_cast<double>(line.pixels.size());
        if (feature_distance(c, *landmarks) < o.feature_radius_px) continue;
      }
      out.lines.push_back(std::move(line));
    }
  // Cluster: boxes closer than the gap merge until none do.
  std::vector<PixelRectI> boxes;
  for (const auto& l : out.lines) boxes.push_back(l.box);
  for (bool merged = true; merged;) {
    merged = false;
    for (std::size_t i = 0; i < boxes.size() && !merged; ++i)
      for (std::size_t j = i + 1; j < boxes.size() && !merged; ++j)
        if (near(boxes[i], boxes[j], o.cluster_gap_px)) {
          boxes[i] = merge(boxes[i], boxes[j]);
          boxes.erase(boxes.begin() + static_cast<long>(j));
          merged = true;
        }
  }
  for (auto b : boxes) {
    const int x0 = std::max(0, b.x - o.margin_px), y0 = std::max(0, b.y - o.margin_px);
    const int x1 = std::min(w, b.x + b.width + o.margin_px),
              y1 = std::min(h, b.y + b.height + o.margin_px);
    out.regions.push_back({x0, y0, x1 - x0, y1 - y0});
  }
  return out;
}

}  // namespace fb
