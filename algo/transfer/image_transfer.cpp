#include "algo/transfer/image_transfer.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include <Eigen/Dense>

#include "algo/core/clock.hpp"
#include "algo/core/polygon.hpp"

namespace fb {

namespace {

using Vec3 = Eigen::Vector3d;

std::vector<double> luminance(const FloatRgb& f) {
  std::vector<double> y(f.r.size());
  for (std::size_t i = 0; i < y.size(); ++i)
    y[i] = 0.299 * f.r[i] + 0.587 * f.g[i] + 0.114 * f.b[i];
  return y;
}

// The face region in the output geometry: jaw line (inset) and brows (raised), >= 2 px from the
// image border so that every region pixel's tent and normal exist.
std::vector<std::uint8_t> face_region(const Landmarks68& p, int width, int height,
                                      const ImageTransferOptions& o) {
  Eigen::Vector2d c = Eigen::Vector2d::Zero();
  for (const auto& q : p) c += q;
  c /= 68.0;
  std::vector<Eigen::Vector2d> polygon;
  for (int k = 0; k <= 16; ++k)
    polygon.push_back(c + (p[static_cast<std::size_t>(k)] - c) * (1.0 - o.contour_inset));
  for (int k = 26; k >= 17; --k)
    polygon.push_back(c + (p[static_cast<std::size_t>(k)] - c) * (1.0 + o.forehead));
  std::vector<std::uint8_t> mask(static_cast<std::size_t>(width) * height, 0);
  for (int y = 2; y < height - 2; ++y)
    for (int x = 2; x < width - 2; ++x)
      mask[static_cast<std::size_t>(y) * width + x] = inside_polygon(polygon, x, y) ? 1 : 0;
  return mask;
}

// City-block distance (px) of every pixel to the region (0 inside), two chamfer passes.
std::vector<float> distance_outside(const std::vector<std::uint8_t>& region, int width,
                                    int height) {
  const float far = 1e9f;
  std::vector<float> d(region.size());
  for (std::size_t i = 0; i < d.size(); ++i) d[i] = region[i] ? 0.0f : far;
  auto at = [&](int x, int y) -> float& { return d[static_cast<std::size_t>(y) * width + x]; };
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      if (x > 0) at(x, y) = std::min(at(x, y), at(x - 1, y) + 1);
      if (y > 0) at(x, y) = std::min(at(x, y), at(x, y - 1) + 1);
    }
  for (int y = height - 1; y >= 0; --y)
    for (int x = width - 1; x >= 0; --x) {
      if (x + 1 < width) at(x, y) = std::min(at(x, y), at(x + 1, y) + 1);
      if (y + 1 < height) at(x, y) = std::min(at(x, y), at(x, y + 1) + 1);
    }
  return d;
}

// One region pixel's equations after its apex height is eliminated: residual = A x - b over the
// pixel and its ring (x at `pixels`), A = P D, b = P q with P the projector that removes the
// apex's direction (the apex height is free, so its component of the residual is always met).
struct TentRows {
  std::array<std::int32_t, 5> pixels{};  // self, right, down, left, up (image indices)
  Eigen::Matrix<double, 3, 5> a;
  Vec3 b;
};

TentRows tent_rows(const std::vector<double>& target_h, const std::vector<double>& source_h,
                   const std::vector<double>& expression_h, int width, int x, int y) {
  const GridTent t = grid_tent(target_h, width, x, y);
  const GridTent s = grid_tent(source_h, width, x, y);
  const GridTent e = grid_tent(expression_h, width, x, y);
  // Third row of the source's Q = w(S^e) w(S)^T (w(S) w(S)^T)^-1: how heights deform.
  const Eigen::RowVector3d q = e.w.row(2) * s.inverse;
  // Target: row 2 of Q_T(x) = sum_k (h_k - h_0) M_k + (apex - h_0) M_apex = q.
  Eigen::Matrix<double, 3, 5> d;
  d.col(0) = -t.inverse.topRows<4>().colwise().sum().transpose();
  for (int k = 0; k < 4; ++k) d.col(k + 1) = t.inverse.row(k).transpose();
  const Vec3 m = t.inverse.row(4).transpose();
  const Eigen::Matrix3d p = Eigen::Matrix3d::Identity() - m * m.transpose() / m.squaredNorm();
  TentRows r;
  const std::int32_t i = y * width + x;
  r.pixels = {i, i + 1, i + width, i - 1, i - width};
  r.a = p * d;
  r.b = p * q.transpose();
  return r;
}

struct Solve {
  std::vector<double> x;  // image luminance (heights), knowns fixed
  int iterations = 0;
  double relative_residual = 0;
};

// The normal matrix sum_p A_p^T A_p couples pixels at most two steps apart (|dx| + |dy| <= 2):
// 13 coefficients per region pixel, applied as a stencil over image-sized vectors (zero outside
// the region), which keeps the conjugate-gradient iterations to sequential memory sweeps.
constexpr int kSlots = 13;

int slot(int dx, int dy) {
  static constexpr std::array<std::array<int, 5>, 5> kTable = {{{-1, -1, 0, -1, -1},
                                                                {-1, 1, 2, 3, -1},
                                                                {4, 5, 6, 7, 8},
                                                                {-1, 9, 10, 11, -1},
                                                                {-1, -1, 12, -1, -1}}};
  return kTable[static_cast<std::size_t>(dy + 2)][static_cast<std::size_t>(dx + 2)];
}

struct Stencil {
  std::vector<std::int32_t> pixels;  // the region's pixels (the unknowns), row-major order
  std::vector<double> coef;          // kSlots per unknown
  std::array<std::ptrdiff_t, kSlots> offset{};
};

Stencil assemble(const std::vector<TentRows>& rows, const std::vector<std::int32_t>& unknown,
                 int width, std::vector<std::int32_t> pixels) {
  Stencil k;
  k.pixels = std::move(pixels);
  k.coef.assign(k.pixels.size() * kSlots, 0.0);
  for (int dy = -2; dy <= 2; ++dy)
    for (int dx = -2; dx <= 2; ++dx)
      if (const int s = slot(dx, dy); s >= 0)
        k.offset[static_cast<std::size_t>(s)] = dy * width + dx;
  const std::array<int, 5> ox = {0, 1, 0, -1, 0}, oy = {0, 0, 1, 0, -1};
  for (const TentRows& r : rows) {
    const Eigen::Matrix<double, 5, 5> ata = r.a.transpose() * r.a;
    for (int i = 0; i < 5; ++i) {
      const auto u = unknown[static_cast<std::size_t>(r.pixels[static_cast<std::size_t>(i)])];
      if (u < 0) continue;
      for (int j = 0; j < 5; ++j) {
        const int s = slot(ox[static_cast<std::size_t>(j)] - ox[static_cast<std::size_t>(i)],
                           oy[static_cast<std::size_t>(j)] - oy[static_cast<std::size_t>(i)]);
        k.coef[static_cast<std::size_t>(u) * kSlots + static_cast<std::size_t>(s)] += ata(i, j);
      }
    }
  }
  return k;
}

// out = K d over the region (d and out image-sized; d zero outside the region).
void apply(const Stencil& k, const std::vector<double>& d, std::vector<double>& out) {
  const double* c = k.coef.data();
  for (std::size_t u = 0; u < k.pixels.size(); ++u, c += kSlots) {
    const double* x = d.data() + k.pixels[u];
    double sum = 0;
    for (std::size_t s = 0; s < kSlots; ++s) sum += c[s] * x[k.offset[s]];
    out[static_cast<std::size_t>(k.pixels[u])] = sum;
  }
}

// min sum |A_p x - b_p|^2 over the region's unknowns, from `x0` (which also holds the known
// values), by Jacobi-preconditioned conjugate gradients.
Solve solve_heights(const std::vector<TentRows>& rows, const std::vector<std::int32_t>& unknown,
                    std::vector<std::int32_t> pixels, int width, std::vector<double> x0,
                    const ImageTransferOptions& o) {
  const Stencil k = assemble(rows, unknown, width, std::move(pixels));
  const std::size_t n = x0.size();
  std::vector<double> r(n, 0.0), z(n, 0.0), p(n, 0.0), kp(n, 0.0), delta(n, 0.0);
  for (const TentRows& t : rows) {  // r = -gradient at x0 = sum A^T (b - A x0)
    Eigen::Matrix<double, 5, 1> v;
    for (int i = 0; i < 5; ++i)
      v[i] = x0[static_cast<std::size_t>(t.pixels[static_cast<std::size_t>(i)])];
    const Eigen::Matrix<double, 5, 1> g = t.a.transpose() * (t.b - t.a * v);
    for (int i = 0; i < 5; ++i) {
      const auto px = static_cast<std::size_t>(t.pixels[static_cast<std::size_t>(i)]);
      if (unknown[px] >= 0) r[px] += g[i];
    }
  }
  std::vector<double> inv_diag(k.pixels.size());
  for (std::size_t u = 0; u < k.pixels.size(); ++u)
    inv_diag[u] = 1.0 / std::max(k.coef[u * kSlots + static_cast<std::size_t>(slot(0, 0))], 1e-12);
  double rz = 0, norm_b = 0;
  for (std::size_t u = 0; u < k.pixels.size(); ++u) {
    const auto i = static_cast<std::size_t>(k.pixels[u]);
    z[i] = inv_diag[u] * r[i];
    p[i] = z[i];
    rz += r[i] * z[i];
    norm_b += r[i] * r[i];
  }
  norm_b = std::sqrt(norm_b);
  Solve s;
  double rn = norm_b;
  // A start that already solves the system (an expression mapped onto its own neutral) has a
  // right-hand side of rounding noise only: nothing to iterate on.
  const double floor = 1e-9 * std::sqrt(static_cast<double>(k.pixels.size()));
  while (s.iterations < o.max_iterations && rn > o.tolerance * norm_b && rn > floor) {
    apply(k, p, kp);
    double pkp = 0;
    for (const std::int32_t i : k.pixels)
      pkp += p[static_cast<std::size_t>(i)] * kp[static_cast<std::size_t>(i)];
    const double alpha = rz / pkp;
    double rz_next = 0, rr = 0;
    for (std::size_t u = 0; u < k.pixels.size(); ++u) {
      const auto i = static_cast<std::size_t>(k.pixels[u]);
      delta[i] += alpha * p[i];
      r[i] -= alpha * kp[i];
      z[i] = inv_diag[u] * r[i];
      rz_next += r[i] * z[i];
      rr += r[i] * r[i];
    }
    rn = std::sqrt(rr);
    ++s.iterations;
    const double beta = rz_next / rz;
    for (const std::int32_t i : k.pixels) {
      const auto j = static_cast<std::size_t>(i);
      p[j] = z[j] + beta * p[j];
    }
    rz = rz_next;
  }
  s.relative_residual = norm_b > 0 ? rn / norm_b : 0.0;
  for (const std::int32_t i : k.pixels)
    x0[static_cast<std::size_t>(i)] += delta[static_cast<std::size_t>(i)];
  s.x = std::move(x0);
  return s;
}

struct Warped {
  FloatRgb target, source, expression;
  ColorImage target_image;
  Landmarks68 landmarks{};
  std::vector<std::uint8_t> region;
};

// The region's bounding box grown by the fade: where the source pair is needed.
PixelRect source_box(const std::vector<std::uint8_t>& region, int width, int height,
                     double feather_px) {
  PixelRect box{width, height, 0, 0};
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x)
      if (region[static_cast<std::size_t>(y) * width + x]) {
        box.x0 = std::min(box.x0, x), box.y0 = std::min(box.y0, y);
        box.x1 = std::max(box.x1, x + 1), box.y1 = std::max(box.y1, y + 1);
      }
  const int grow = static_cast<int>(std::ceil(feather_px)) + 3;
  return {box.x0 - grow, box.y0 - grow, box.x1 + grow, box.y1 + grow};
}

Result<Warped> warp_all(const FacePhoto& sn, const FacePhoto& se, const FacePhoto& t,
                        const ImageTransferOptions& o) {
  auto g = expression_geometry(sn.points, se.points, t.points);
  if (!g) return g.failure();
  const int w = t.image.width, h = t.image.height;
  const Similarity2d identity;
  Similarity2d expression_from_target;
  expression_from_target.linear = g->expression_from_source.linear * g->source_from_target.linear;
  expression_from_target.translation =
      g->expression_from_source.apply(g->source_from_target.translation);
  const auto target_controls = control_points(t.points, w, h, identity);
  const WarpMesh mesh = warp_mesh(target_controls);
  const WarpMap map = warp_map(mesh, control_points(g->target_expression, w, h, identity), w, h);
  Warped out;
  out.landmarks = g->target_expression;
  out.region = face_region(out.landmarks, w, h, o);
  const PixelRect box = source_box(out.region, w, h, o.feather_px);
  out.target = warp_image(t.image, mesh, map, target_controls, identity);
  out.source =
      warp_image(sn.image, mesh, map, control_points(sn.points, w, h, g->source_from_target),
                 g->source_from_target, box);
  out.expression =
      warp_image(se.image, mesh, map, control_points(se.points, w, h, expression_from_target),
                 expression_from_target, box);
  out.target_image = to_color_image(out.target);
  return out;
}

}  // namespace

GridTent grid_tent(const std::vector<double>& heights, int width, int x, int y) {
  auto v = [&](int u, int w) {
    return Vec3(u, w, heights[static_cast<std::size_t>(w) * width + u]);
  };
  // Newell's vector of a quad (twice its vector area).
  auto newell = [](const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
    return Vec3(a.cross(b) + b.cross(c) + c.cross(d) + d.cross(a));
  };
  const Vec3 n = (newell(v(x, y), v(x + 1, y), v(x + 1, y + 1), v(x, y + 1)) +
                  newell(v(x - 1, y), v(x, y), v(x, y + 1), v(x - 1, y + 1)) +
                  newell(v(x - 1, y - 1), v(x, y - 1), v(x, y), v(x - 1, y)) +
                  newell(v(x, y - 1), v(x + 1, y - 1), v(x + 1, y), v(x, y)))
                     .normalized();
  const Vec3 v0 = v(x, y);
  GridTent t;
  t.w.col(0) = v(x + 1, y) - v0;
  t.w.col(1) = v(x, y + 1) - v0;
  t.w.col(2) = v(x - 1, y) - v0;
  t.w.col(3) = v(x, y - 1) - v0;
  const double length =
      (t.w.col(0).norm() + t.w.col(1).norm() + t.w.col(2).norm() + t.w.col(3).norm()) / 4.0;
  t.w.col(4) = n * length;
  // The grid's tents always span 3D (two ring directions in x and y, the apex out of plane).
  t.inverse = t.w.transpose() * (t.w * t.w.transpose()).inverse();
  return t;
}

Result<ImageTransferResult> transfer_image_expression(const FacePhoto& source_neutral,
                                                      const FacePhoto& source_expression,
                                                      const FacePhoto& target,
                                                      const ImageTransferOptions& options) {
  if (source_neutral.image.empty() || source_expression.image.empty() || target.image.empty())
    return fail("an image is empty");
  if (source_neutral.image.width != source_expression.image.width ||
      source_neutral.image.height != source_expression.image.height)
    return fail("the source neutral and expression photographs differ in size (" +
                std::to_string(source_neutral.image.width) + "x" +
                std::to_string(source_neutral.image.height) + " and " +
                std::to_string(source_expression.image.width) + "x" +
                std::to_string(source_expression.image.height) +
                "): take both with the same camera and crop");
  const int w = target.image.width, h = target.image.height;
  if (w < 8 || h < 8) return fail("the target image is smaller than 8 x 8 px");
  const auto t0 = Clock::now();
  auto warped = warp_all(source_neutral, source_expression, target, options);
  if (!warped) return warped.failure();
  ImageTransferResult out;
  out.warp_ms = ms_since(t0);
  const auto t1 = Clock::now();
  const std::vector<std::uint8_t>& region = warped->region;
  const std::vector<double> yt = luminance(warped->target), ys = luminance(warped->source),
                            ye = luminance(warped->expression);
  const double k = options.luminance_height;
  auto heights = [k](const std::vector<double>& y) {
    std::vector<double> out(y.size());
    for (std::size_t i = 0; i < y.size(); ++i) out[i] = k * y[i];
    return out;
  };
  const std::vector<double> ht = heights(yt), hs = heights(ys), he = heights(ye);
  // Start (and boundary): the additive change, faded out beyond the region.
  const std::vector<float> dist = distance_outside(region, w, h);
  std::vector<double> x0(ht.size());
  std::vector<float> fade(ht.size());
  for (std::size_t i = 0; i < x0.size(); ++i) {
    fade[i] =
        std::clamp(1.0f - (dist[i] - 1.0f) / static_cast<float>(options.feather_px), 0.0f, 1.0f);
    x0[i] = ht[i] + fade[i] * (he[i] - hs[i]);
  }
  std::vector<std::int32_t> unknown(region.size(), -1), pixels;
  std::vector<TentRows> rows;
  int count = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * w + x;
      if (!region[i]) continue;
      unknown[i] = count++;
      pixels.push_back(static_cast<std::int32_t>(i));
      rows.push_back(tent_rows(ht, hs, he, w, x, y));
    }
  Solve s = solve_heights(rows, unknown, std::move(pixels), w, std::move(x0), options);
  // Back to colour: the new luminance with the warped target's chromaticity (R / Y, B / Y)
  // plus the source's change of it (additive, faded as the luminance start). The paper keeps
  // the target's chroma; the source's change carries what the expression uncovers (a mouth
  // cavity is dark red, not stretched lip). Ratios, not differences (R - Y): a colour
  // difference shrinks with the luminance, so adding a bright lip's loss of it to a dark
  // cavity's would overshoot into blue.
  FloatRgb rgb = warped->target;
  const FloatRgb& fs = warped->source;
  const FloatRgb& fe = warped->expression;
  constexpr double kDark = 4.0;  // luminance floor of the ratios (levels)
  for (std::size_t i = 0; i < s.x.size(); ++i) {
    const double y = std::max(s.x[i] / k, 0.0), f = fade[i];
    auto ratio = [&](double c, double luma) { return c / (luma + kDark); };
    const double r = ratio(rgb.r[i], yt[i]) + f * (ratio(fe.r[i], ye[i]) - ratio(fs.r[i], ys[i]));
    const double b = ratio(rgb.b[i], yt[i]) + f * (ratio(fe.b[i], ye[i]) - ratio(fs.b[i], ys[i]));
    rgb.r[i] = static_cast<float>(std::max(r, 0.0) * (y + kDark));
    rgb.b[i] = static_cast<float>(std::max(b, 0.0) * (y + kDark));
    rgb.g[i] = static_cast<float>((y - 0.299 * rgb.r[i] - 0.114 * rgb.b[i]) / 0.587);
  }
  out.image = to_color_image(rgb);
  out.warped = std::move(warped->target_image);
  out.landmarks = warped->landmarks;
  out.region_pixels = count;
  out.iterations = s.iterations;
  out.relative_residual = s.relative_residual;
  out.solve_ms = ms_since(t1);
  return out;
}

}  // namespace fb
