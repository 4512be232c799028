#include "algo/wrinkles/exemplar.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

namespace fb {

namespace {

float at_clamped(const FloatImage& in, int x, int y) {
  return in.at(std::clamp(x, 0, in.width - 1), std::clamp(y, 0, in.height - 1));
}

float bilinear(const FloatImage& in, double x, double y) {
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  const auto ax = static_cast<float>(x - x0), ay = static_cast<float>(y - y0);
  return (1 - ay) * ((1 - ax) * at_clamped(in, x0, y0) + ax * at_clamped(in, x0 + 1, y0)) +
         ay * ((1 - ax) * at_clamped(in, x0, y0 + 1) + ax * at_clamped(in, x0 + 1, y0 + 1));
}

}  // namespace

FloatImage gaussian_blur(const FloatImage& in, double sigma_px) {
  if (sigma_px <= 0.0 || in.empty()) return in;
  const int r = std::max(1, static_cast<int>(std::ceil(3.0 * sigma_px)));
  std::vector<float> k(static_cast<std::size_t>(2 * r + 1));
  float sum = 0.0f;
  for (int i = -r; i <= r; ++i) {
    k[static_cast<std::size_t>(i + r)] =
        static_cast<float>(std::exp(-0.5 * i * i / (sigma_px * sigma_px)));
    sum += k[static_cast<std::size_t>(i + r)];
  }
  for (auto& v : k) v /= sum;
  FloatImage tmp, out;
  tmp.resize(in.width, in.height);
  out.resize(in.width, in.height);
  for (int y = 0; y < in.height; ++y)
    for (int x = 0; x < in.width; ++x) {
      float s = 0.0f;
      for (int i = -r; i <= r; ++i)
        s += k[static_cast<std::size_t>(i + r)] * at_clamped(in, x + i, y);
      tmp.at(x, y) = s;
    }
  for (int y = 0; y < in.height; ++y)
    for (int x = 0; x < in.width; ++x) {
      float s = 0.0f;
      for (int i = -r; i <= r; ++i)
        s += k[static_cast<std::size_t>(i + r)] * at_clamped(tmp, x, y + i);
      out.at(x, y) = s;
    }
  return out;
}

FloatImage high_pass(const FloatImage& in, double sigma_px) {
  FloatImage out = gaussian_blur(in, sigma_px);
  for (std::size_t i = 0; i < out.pixels.size(); ++i) out.pixels[i] = in.pixels[i] - out.pixels[i];
  return out;
}

FloatImage resample(const FloatImage& in, double scale) {
  const FloatImage& src = scale < 1.0 ? gaussian_blur(in, 0.5 / scale) : in;
  FloatImage out;
  out.resize(std::max(1, static_cast<int>(std::lround(in.width * scale))),
             std::max(1, static_cast<int>(std::lround(in.height * scale))));
  for (int y = 0; y < out.height; ++y)
    for (int x = 0; x < out.width; ++x)
      out.at(x, y) = bilinear(src, (x + 0.5) / scale - 0.5, (y + 0.5) / scale - 0.5);
  return out;
}

FloatImage rotate_square(const FloatImage& in, double degrees, int side) {
  const double a = degrees * M_PI / 180.0, c = std::cos(a), s = std::sin(a);
  const double cx = (in.width - 1) / 2.0, cy = (in.height - 1) / 2.0, h = (side - 1) / 2.0;
  FloatImage out;
  out.resize(side, side);
  for (int y = 0; y < side; ++y)
    for (int x = 0; x < side; ++x) {
      // Output pixel -> source: the inverse rotation.
      const double dx = x - h, dy = y - h;
      out.at(x, y) = bilinear(in, cx + c * dx + s * dy, cy - s * dx + c * dy);
    }
  return out;
}

FloatImage shade_relief(const FloatImage& height_mm, double mm_per_px, const SkinLight& light) {
  FloatImage out;
  out.resize(height_mm.width, height_mm.height);
  const double step = 2.0 * mm_per_px;
  for (int y = 0; y < height_mm.height; ++y)
    for (int x = 0; x < height_mm.width; ++x) {
      // Image y runs down; the surface's y axis up, so the light's "upper" comes from -y.
      const double dzdx =
          (at_clamped(height_mm, x + 1, y) - at_clamped(height_mm, x - 1, y)) / step;
      const double dzdy =
          (at_clamped(height_mm, x, y - 1) - at_clamped(height_mm, x, y + 1)) / step;
      const Eigen::Vector3f n =
          Eigen::Vector3f(static_cast<float>(-dzdx), static_cast<float>(-dzdy), 1.0f).normalized();
      const Eigen::Vector3f l(light.to_light.x(), -light.to_light.y(), light.to_light.z());
      out.at(x, y) = std::clamp(
          light.albedo * (light.ambient + light.diffuse * std::max(0.0f, n.dot(l))), 0.0f, 1.0f);
    }
  return out;
}

ImageGradient image_gradient(const FloatImage& in) {
  ImageGradient g;
  g.gx.resize(in.width, in.height);
  g.gy.resize(in.width, in.height);
  for (int y = 0; y < in.height; ++y)
    for (int x = 0; x < in.width; ++x) {
      g.gx.at(x, y) = 0.5f * (at_clamped(in, x + 1, y) - at_clamped(in, x - 1, y));
      g.gy.at(x, y) = 0.5f * (at_clamped(in, x, y + 1) - at_clamped(in, x, y - 1));
    }
  return g;
}

}  // namespace fb
