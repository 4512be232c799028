#include "algo/photo/mesh_warp.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "algo/core/polygon.hpp"

namespace fb {
namespace {

// Per output pixel: where to sample the photo, and what drew it.
enum class Cover : std::uint8_t { kNone, kMesh, kMouth };

struct Maps {
  int width = 0, height = 0;
  std::vector<float> depth;
  std::vector<Eigen::Vector2f> source;
  std::vector<Cover> cover;
  std::size_t at(int x, int y) const { return static_cast<std::size_t>(y) * width + x; }
};

float signed_area(const Eigen::Vector2f& a, const Eigen::Vector2f& b, const Eigen::Vector2f& c) {
  return (b.x() - a.x()) * (c.y() - a.y()) - (b.y() - a.y()) * (c.x() - a.x());
}

// The winding of the triangles that face the camera in the photo: the sign most of the
// projected area has (a face seen from the front shows mostly its front).
float front_sign(const MeshWarpInput& in) {
  double sum = 0;
  for (std::size_t t = 0; t + 2 < in.triangles.size(); t += 3)
    sum += signed_area(in.source[in.triangles[t]], in.source[in.triangles[t + 1]],
                       in.source[in.triangles[t + 2]]);
  return sum >= 0 ? 1.0f : -1.0f;
}

void rasterize(const MeshWarpInput& in, Maps& m) {
  const float inf = std::numeric_limits<float>::infinity();
  m.depth.assign(static_cast<std::size_t>(m.width) * m.height, inf);
  const float front = front_sign(in);
  for (std::size_t t = 0; t + 2 < in.triangles.size(); t += 3) {
    const std::uint32_t i[3] = {in.triangles[t], in.triangles[t + 1], in.triangles[t + 2]};
    const Eigen::Vector3f& a = in.target[i[0]];
    const Eigen::Vector3f& b = in.target[i[1]];
    const Eigen::Vector3f& c = in.target[i[2]];
    const float area = signed_area(a.head<2>(), b.head<2>(), c.head<2>());
    if (std::abs(area) < 1e-6f || !std::isfinite(area)) continue;
    // A triangle turned away in the result is hidden (the z-buffer alone would let the thin
    // back of a fold through at its edges). One hidden in the photo keeps what the photo shows
    // in its place: for the inner lips the lips, which is what a closed mouth gives.
    if (area * front <= 0) continue;
    const int x0 = std::max(0, static_cast<int>(std::floor(std::min({a.x(), b.x(), c.x()}))));
    const int x1 =
        std::min(m.width - 1, static_cast<int>(std::ceil(std::max({a.x(), b.x(), c.x()}))));
    const int y0 = std::max(0, static_cast<int>(std::floor(std::min({a.y(), b.y(), c.y()}))));
    const int y1 =
        std::min(m.height - 1, static_cast<int>(std::ceil(std::max({a.y(), b.y(), c.y()}))));
    const float eps = -1e-4f;
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) {
        const float px = static_cast<float>(x), py = static_cast<float>(y);
        const float l1 = ((px - a.x()) * (c.y() - a.y()) - (py - a.y()) * (c.x() - a.x())) / area;
        const float l2 = ((b.x() - a.x()) * (py - a.y()) - (b.y() - a.y()) * (px - a.x())) / area;
        const float l0 = 1.0f - l1 - l2;
        if (l0 < eps || l1 < eps || l2 < eps) continue;
        const float z = l0 * a.z() + l1 * b.z() + l2 * c.z();
        const std::size_t k = m.at(x, y);
        if (z >= m.depth[k]) continue;
        m.depth[k] = z;
        m.source[k] = l0 * in.source[i[0]] + l1 * in.source[i[1]] + l2 * in.source[i[2]];
        m.cover[k] = Cover::kMesh;
      }
  }
}

void mark_mouth(std::span<const Eigen::Vector2f> mouth, Maps& m) {
  if (mouth.size() < 3) return;
  float x0 = mouth[0].x(), x1 = x0, y0 = mouth[0].y(), y1 = y0;
  for (const auto& p : mouth) {
    x0 = std::min(x0, p.x());
    x1 = std::max(x1, p.x());
    y0 = std::min(y0, p.y());
    y1 = std::max(y1, p.y());
  }
  for (int y = std::max(0, static_cast<int>(y0));
       y <= std::min(m.height - 1, static_cast<int>(y1) + 1); ++y)
    for (int x = std::max(0, static_cast<int>(x0));
         x <= std::min(m.width - 1, static_cast<int>(x1) + 1); ++x) {
      const std::size_t k = m.at(x, y);
      if (m.cover[k] == Cover::kNone &&
          inside_polygon(mouth, static_cast<float>(x), static_cast<float>(y)))
        m.cover[k] = Cover::kMouth;
    }
}

// Nearest mesh-covered pixel of every pixel: two raster passes propagating the nearest seed
// (8-neighbour; within a pixel or so of the exact Euclidean answer, plenty for a fade).
std::vector<int> nearest_covered(const Maps& m) {
  const int n = m.width * m.height;
  std::vector<int> seed(static_cast<std::size_t>(n), -1);
  for (int k = 0; k < n; ++k)
    if (m.cover[static_cast<std::size_t>(k)] == Cover::kMesh) seed[static_cast<std::size_t>(k)] = k;
  auto dist2 = [&](int k, int s) {
    const int dx = k % m.width - s % m.width, dy = k / m.width - s / m.width;
    return dx * dx + dy * dy;
  };
  auto relax = [&](int x, int y, int nx, int ny) {
    if (nx < 0 || ny < 0 || nx >= m.width || ny >= m.height) return;
    const int k = y * m.width + x;
    const int s = seed[static_cast<std::size_t>(ny * m.width + nx)];
    if (s < 0) return;
    int& mine = seed[static_cast<std::size_t>(k)];
    if (mine < 0 || dist2(k, s) < dist2(k, mine)) mine = s;
  };
  for (int y = 0; y < m.height; ++y)
    for (int x = 0; x < m.width; ++x) {
      relax(x, y, x - 1, y);
      relax(x, y, x - 1, y - 1);
      relax(x, y, x, y - 1);
      relax(x, y, x + 1, y - 1);
    }
  for (int y = m.height - 1; y >= 0; --y)
    for (int x = m.width - 1; x >= 0; --x) {
      relax(x, y, x + 1, y);
      relax(x, y, x + 1, y + 1);
      relax(x, y, x, y + 1);
      relax(x, y, x - 1, y + 1);
    }
  return seed;
}

// The shift (source - pixel) of every pixel the mesh does not cover: its nearest covered
// pixel's, faded to zero over `reach` px (smoothstep), then box-blurred (radius `blur`, twice)
// so neighbouring pixels whose nearest covered pixels differ do not tear apart.
std::vector<Eigen::Vector2f> fill_shifts(const Maps& m, float reach, int blur) {
  const std::vector<int> seed = nearest_covered(m);
  std::vector<Eigen::Vector2f> shift(seed.size(), Eigen::Vector2f::Zero());
  for (int y = 0; y < m.height; ++y)
    for (int x = 0; x < m.width; ++x) {
      const std::size_t k = m.at(x, y);
      const Eigen::Vector2f p(static_cast<float>(x), static_cast<float>(y));
      if (m.cover[k] == Cover::kMesh) {
        shift[k] = m.source[k] - p;
        continue;
      }
      const int s = seed[k];
      if (s < 0) continue;
      const Eigen::Vector2f q(static_cast<float>(s % m.width), static_cast<float>(s / m.width));
      const float d = (p - q).norm() / reach;
      if (d >= 1.0f) continue;
      shift[k] = (1.0f - d * d * (3.0f - 2.0f * d)) * (m.source[static_cast<std::size_t>(s)] - q);
    }
  std::vector<Eigen::Vector2f> tmp(shift.size());
  for (int pass = 0; pass < 2; ++pass) {
    // Horizontal then vertical running sums; covered pixels keep their exact shift.
    for (int y = 0; y < m.height; ++y)
      for (int x = 0; x < m.width; ++x) {
        Eigen::Vector2f sum = Eigen::Vector2f::Zero();
        const int a = std::max(0, x - blur), b = std::min(m.width - 1, x + blur);
        for (int u = a; u <= b; ++u) sum += shift[m.at(u, y)];
        tmp[m.at(x, y)] = sum / static_cast<float>(b - a + 1);
      }
    for (int y = 0; y < m.height; ++y)
      for (int x = 0; x < m.width; ++x) {
        const std::size_t k = m.at(x, y);
        if (m.cover[k] == Cover::kMesh) continue;
        Eigen::Vector2f sum = Eigen::Vector2f::Zero();
        const int a = std::max(0, y - blur), b = std::min(m.height - 1, y + blur);
        for (int v = a; v <= b; ++v) sum += tmp[m.at(x, v)];
        shift[k] = sum / static_cast<float>(b - a + 1);
      }
  }
  return shift;
}

Rgb8 sample(const ColorImage& img, float x, float y) {
  x = std::clamp(x, 0.0f, static_cast<float>(img.width - 1));
  y = std::clamp(y, 0.0f, static_cast<float>(img.height - 1));
  const int x0 = std::min(static_cast<int>(x), img.width - 2 < 0 ? 0 : img.width - 2);
  const int y0 = std::min(static_cast<int>(y), img.height - 2 < 0 ? 0 : img.height - 2);
  const int x1 = std::min(x0 + 1, img.width - 1), y1 = std::min(y0 + 1, img.height - 1);
  const float fx = x - static_cast<float>(x0), fy = y - static_cast<float>(y0);
  auto mix = [&](auto channel) {
    const float top = (1 - fx) * channel(img.at(x0, y0)) + fx * channel(img.at(x1, y0));
    const float bottom = (1 - fx) * channel(img.at(x0, y1)) + fx * channel(img.at(x1, y1));
    return static_cast<std::uint8_t>(std::clamp((1 - fy) * top + fy * bottom + 0.5f, 0.0f, 255.0f));
  };
  return {mix([](Rgb8 p) { return static_cast<float>(p.r); }),
          mix([](Rgb8 p) { return static_cast<float>(p.g); }),
          mix([](Rgb8 p) { return static_cast<float>(p.b); })};
}

}  // namespace

Result<ColorImage> warp_photo(const ColorImage& photo, const MeshWarpInput& in,
                              const MeshWarpOptions& options, MeshWarpStats* stats) {
  if (photo.empty()) return fail("mesh warp: the photo is empty");
  if (in.source.size() != in.target.size())
    return fail("mesh warp: " + std::to_string(in.source.size()) + " source and " +
                std::to_string(in.target.size()) + " target vertices");
  for (std::uint32_t i : in.triangles)
    if (i >= in.source.size()) return fail("mesh warp: a triangle indexes past the vertices");
  Maps m;
  m.width = photo.width;
  m.height = photo.height;
  const std::size_t n = static_cast<std::size_t>(m.width) * m.height;
  m.source.assign(n, Eigen::Vector2f::Zero());
  m.cover.assign(n, Cover::kNone);
  rasterize(in, m);
  if (options.mouth_cavity) mark_mouth(in.mouth, m);

  // The face's size: the covered pixels' bounding box.
  int x0 = m.width, x1 = -1, y0 = m.height, y1 = -1;
  MeshWarpStats st;
  for (int y = 0; y < m.height; ++y)
    for (int x = 0; x < m.width; ++x) {
      const std::size_t k = m.at(x, y);
      if (m.cover[k] == Cover::kMouth) ++st.mouth_pixels;
      if (m.cover[k] != Cover::kMesh) continue;
      ++st.covered_pixels;
      st.max_shift_px =
          std::max(st.max_shift_px,
                   static_cast<double>(
                       (m.source[k] - Eigen::Vector2f(static_cast<float>(x), static_cast<float>(y)))
                           .norm()));
      x0 = std::min(x0, x);
      x1 = std::max(x1, x);
      y0 = std::min(y0, y);
      y1 = std::max(y1, y);
    }
  if (stats) *stats = st;
  ColorImage out = photo;
  if (st.covered_pixels == 0) return out;  // the mesh is off the image: nothing moves
  const float reach =
      std::max(1.0f, static_cast<float>(options.falloff * std::max(x1 - x0, y1 - y0)));
  std::vector<Eigen::Vector2f> shift = fill_shifts(m, reach, std::max(1, (x1 - x0) / 40));
  for (int y = 0; y < m.height; ++y)
    for (int x = 0; x < m.width; ++x) {
      const std::size_t k = m.at(x, y);
      if (m.cover[k] == Cover::kMouth) {
        out.at(x, y) = options.mouth_color;
      } else if (m.cover[k] == Cover::kMesh) {
        out.at(x, y) = sample(photo, m.source[k].x(), m.source[k].y());
      } else if (shift[k].squaredNorm() > 1e-6f) {
        out.at(x, y) = sample(photo, static_cast<float>(x) + shift[k].x(),
                              static_cast<float>(y) + shift[k].y());
      }
    }
  return out;
}

}  // namespace fb
