#include "algo/transfer/image_warp.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

#include <Eigen/LU>

#include "algo/transfer/correspondence.hpp"

namespace fb {

Similarity2d Similarity2d::inverse() const {
  Similarity2d inv;
  inv.linear = linear.inverse();
  inv.translation = -inv.linear * translation;
  return inv;
}

Result<Similarity2d> align_similarity_2d(const Landmarks68& from, const Landmarks68& to,
                                         const std::vector<int>& subset) {
  std::vector<int> use = subset;
  if (use.empty()) {
    use.resize(from.size());
    std::iota(use.begin(), use.end(), 0);
  }
  Eigen::Vector2d cf = Eigen::Vector2d::Zero(), ct = Eigen::Vector2d::Zero();
  for (int i : use) cf += from[static_cast<std::size_t>(i)], ct += to[static_cast<std::size_t>(i)];
  cf /= static_cast<double>(use.size());
  ct /= static_cast<double>(use.size());
  // Closed form in the complex plane: (a + ib) = sum conj(x) y / sum |x|^2.
  double a = 0, b = 0, norm = 0;
  for (int i : use) {
    const Eigen::Vector2d x = from[static_cast<std::size_t>(i)] - cf;
    const Eigen::Vector2d y = to[static_cast<std::size_t>(i)] - ct;
    a += x.dot(y);
    b += x.x() * y.y() - x.y() * y.x();
    norm += x.squaredNorm();
  }
  if (norm < 1e-6) return fail("the landmarks coincide: no face to align");
  Similarity2d s;
  s.linear << a / norm, -b / norm, b / norm, a / norm;
  s.translation = ct - s.linear * cf;
  return s;
}

const std::vector<int>& rigid_landmarks() {
  // Measured on the synthetic photographs: the eye corners and the contour's ends move <= 0.6 px
  // under smile, jaw open, brows up, blink, pucker and sneer; the nose bridge (27) moves 3 px
  // with raised brows and the nostrils (31, 35) 5 px with a sneer.
  static const std::vector<int> kRigid = {0, 16, 36, 39, 42, 45};
  return kRigid;
}

namespace {

constexpr int kBorderPerEdge = 4;  // border points per image edge (corners included once)

std::vector<Eigen::Vector2d> border_points(int width, int height) {
  std::vector<Eigen::Vector2d> out;
  const double w = width - 1.0, h = height - 1.0;
  for (int k = 0; k < kBorderPerEdge; ++k) {
    const double t = static_cast<double>(k) / kBorderPerEdge;
    out.emplace_back(t * w, 0.0);
    out.emplace_back(w, t * h);
    out.emplace_back(w - t * w, h);
    out.emplace_back(0.0, h - t * h);
  }
  return out;
}

double signed_area(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
  return 0.5 * ((b - a).x() * (c - a).y() - (b - a).y() * (c - a).x());
}

FloatRgb planes_of(const ColorImage& image) {
  FloatRgb f;
  f.width = image.width;
  f.height = image.height;
  const std::size_t n = image.pixels.size();
  f.r.resize(n), f.g.resize(n), f.b.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    f.r[i] = image.pixels[i].r, f.g[i] = image.pixels[i].g, f.b[i] = image.pixels[i].b;
  }
  return f;
}

}  // namespace

std::vector<Eigen::Vector2d> control_points(const Landmarks68& landmarks, int target_width,
                                            int target_height,
                                            const Similarity2d& image_from_target) {
  std::vector<Eigen::Vector2d> out(landmarks.begin(), landmarks.end());
  for (const auto& p : border_points(target_width, target_height))
    out.push_back(image_from_target.apply(p));
  return out;
}

WarpMesh warp_mesh(const std::vector<Eigen::Vector2d>& target_controls) {
  // A closed mouth puts the inner lip points (61-63 over 67-65) on top of each other: the
  // triangulation is built with them pulled 1 px apart (its topology only; every photograph
  // keeps its own positions), and any other coincident point is nudged likewise.
  std::vector<Eigen::Vector2d> p = target_controls;
  for (int i : {61, 62, 63}) p[static_cast<std::size_t>(i)].y() -= 1.0;
  for (int i : {65, 66, 67}) p[static_cast<std::size_t>(i)].y() += 1.0;
  for (std::size_t i = 1; i < p.size(); ++i)
    for (std::size_t j = 0; j < i; ++j)
      if ((p[i] - p[j]).norm() < 0.5) p[i].x() += 0.7;
  WarpMesh mesh;
  mesh.triangles = delaunay(p);  // counter-clockwise: positive signed_area()
  return mesh;
}

WarpMap warp_map(const WarpMesh& mesh, const std::vector<Eigen::Vector2d>& output_controls,
                 int width, int height) {
  WarpMap map;
  map.width = width;
  map.height = height;
  const std::size_t n = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
  map.triangle.assign(n, -1);
  map.b1.assign(n, 0.0f);
  map.b2.assign(n, 0.0f);
  for (std::size_t t = 0; 3 * t < mesh.triangles.size(); ++t) {
    const auto& a = output_controls[mesh.triangles[3 * t]];
    const auto& b = output_controls[mesh.triangles[3 * t + 1]];
    const auto& c = output_controls[mesh.triangles[3 * t + 2]];
    const double area = signed_area(a, b, c);
    if (area <= 1e-9) continue;  // folded or collapsed in the output geometry
    const int x0 = std::max(0, static_cast<int>(std::floor(std::min({a.x(), b.x(), c.x()}))));
    const int x1 =
        std::min(width - 1, static_cast<int>(std::ceil(std::max({a.x(), b.x(), c.x()}))));
    const int y0 = std::max(0, static_cast<int>(std::floor(std::min({a.y(), b.y(), c.y()}))));
    const int y1 =
        std::min(height - 1, static_cast<int>(std::ceil(std::max({a.y(), b.y(), c.y()}))));
    const double eps = -1e-9 * area;
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) {
        const Eigen::Vector2d q(x, y);
        const double w1 = signed_area(a, q, c) / area, w2 = signed_area(a, b, q) / area;
        if (w1 < eps || w2 < eps || 1.0 - w1 - w2 < eps) continue;
        const std::size_t i = static_cast<std::size_t>(y) * width + x;
        map.triangle[i] = static_cast<std::int32_t>(t);
        map.b1[i] = static_cast<float>(w1);
        map.b2[i] = static_cast<float>(w2);
      }
  }
  return map;
}

FloatRgb warp_image(const ColorImage& source, const WarpMesh& mesh, const WarpMap& map,
                    const std::vector<Eigen::Vector2d>& source_controls,
                    const Similarity2d& fallback, const PixelRect& box) {
  const FloatRgb in = planes_of(source);
  FloatRgb out;
  out.width = map.width;
  out.height = map.height;
  const std::size_t n = map.triangle.size();
  out.r.assign(n, 0.0f), out.g.assign(n, 0.0f), out.b.assign(n, 0.0f);
  const int x_end = std::min(box.x1, map.width), y_end = std::min(box.y1, map.height);
  const double xmax = in.width - 1.0, ymax = in.height - 1.0;
  for (int y = std::max(box.y0, 0); y < y_end; ++y)
    for (int x = std::max(box.x0, 0); x < x_end; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * map.width + x;
      Eigen::Vector2d s;
      if (const std::int32_t t = map.triangle[i]; t >= 0) {
        const auto k = static_cast<std::size_t>(t);
        const double w1 = map.b1[i], w2 = map.b2[i];
        s = (1 - w1 - w2) * source_controls[mesh.triangles[3 * k]] +
            w1 * source_controls[mesh.triangles[3 * k + 1]] +
            w2 * source_controls[mesh.triangles[3 * k + 2]];
      } else {
        s = fallback.apply(Eigen::Vector2d(x, y));
      }
      // Bilinear, clamped to the image.
      const double sx = std::clamp(s.x(), 0.0, xmax), sy = std::clamp(s.y(), 0.0, ymax);
      const int x0 = std::min(static_cast<int>(sx), std::max(in.width - 2, 0));
      const int y0 = std::min(static_cast<int>(sy), std::max(in.height - 2, 0));
      const int x1 = std::min(x0 + 1, in.width - 1), y1 = std::min(y0 + 1, in.height - 1);
      const auto ax = static_cast<float>(sx - x0), ay = static_cast<float>(sy - y0);
      const std::size_t a = static_cast<std::size_t>(y0) * in.width + x0;
      const std::size_t b = static_cast<std::size_t>(y0) * in.width + x1;
      const std::size_t c = static_cast<std::size_t>(y1) * in.width + x0;
      const std::size_t d = static_cast<std::size_t>(y1) * in.width + x1;
      const float wa = (1 - ax) * (1 - ay), wb = ax * (1 - ay), wc = (1 - ax) * ay, wd = ax * ay;
      out.r[i] = wa * in.r[a] + wb * in.r[b] + wc * in.r[c] + wd * in.r[d];
      out.g[i] = wa * in.g[a] + wb * in.g[b] + wc * in.g[c] + wd * in.g[d];
      out.b[i] = wa * in.b[a] + wb * in.b[b] + wc * in.b[c] + wd * in.b[d];
    }
  return out;
}

ColorImage to_color_image(const FloatRgb& image) {
  ColorImage out;
  out.resize(image.width, image.height);
  auto byte = [](float v) {
    return static_cast<std::uint8_t>(std::clamp(std::lround(v), 0L, 255L));
  };
  for (std::size_t i = 0; i < out.pixels.size(); ++i)
    out.pixels[i] = {byte(image.r[i]), byte(image.g[i]), byte(image.b[i])};
  return out;
}

Result<ExpressionGeometry> expression_geometry(const Landmarks68& source_neutral,
                                               const Landmarks68& source_expression,
                                               const Landmarks68& target) {
  auto target_from_source = align_similarity_2d(source_neutral, target);
  if (!target_from_source) return target_from_source.failure();
  auto source_from_expression =
      align_similarity_2d(source_expression, source_neutral, rigid_landmarks());
  if (!source_from_expression) return source_from_expression.failure();
  ExpressionGeometry g;
  g.source_from_target = target_from_source->inverse();
  g.expression_from_source = source_from_expression->inverse();
  for (std::size_t k = 0; k < 68; ++k) {
    const Eigen::Vector2d motion =
        source_from_expression->apply(source_expression[k]) - source_neutral[k];
    g.target_expression[k] = target[k] + target_from_source->linear * motion;
  }
  return g;
}

Result<ColorImage> warp_expression(const FacePhoto& source_neutral,
                                   const FacePhoto& source_expression, const FacePhoto& target) {
  if (target.image.empty()) return fail("the target image is empty");
  auto g = expression_geometry(source_neutral.points, source_expression.points, target.points);
  if (!g) return g.failure();
  const int w = target.image.width, h = target.image.height;
  const Similarity2d identity;
  const auto target_controls = control_points(target.points, w, h, identity);
  const WarpMesh mesh = warp_mesh(target_controls);
  const WarpMap map = warp_map(mesh, control_points(g->target_expression, w, h, identity), w, h);
  return to_color_image(warp_image(target.image, mesh, map, target_controls, identity));
}

}  // namespace fb
