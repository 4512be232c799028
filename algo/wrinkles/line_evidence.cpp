#include "algo/wrinkles/line_evidence.hpp"

#include <algorithm>
#include <cmath>
#include <map>

#include <Eigen/Eigenvalues>

namespace fb {

namespace {

float sample(const FloatImage& im, double x, double y) {
  x = std::clamp(x, 0.0, im.width - 1.0);
  y = std::clamp(y, 0.0, im.height - 1.0);
  const int x0 = std::min(static_cast<int>(x), im.width - 2);
  const int y0 = std::min(static_cast<int>(y), im.height - 2);
  const int x1 = x0 + 1, y1 = y0 + 1;
  const double fx = x - x0, fy = y - y0;
  return static_cast<float>((1 - fy) * ((1 - fx) * im.at(x0, y0) + fx * im.at(x1, y0)) +
                            fy * ((1 - fx) * im.at(x0, y1) + fx * im.at(x1, y1)));
}

// 0.5 (D(q + o d) + D(q - o d)) - D(q).
double second_difference(const FloatImage& im, const Eigen::Vector2d& q, const Eigen::Vector2d& d,
                         double o) {
  const Eigen::Vector2d a = q + o * d, b = q - o * d;
  return 0.5 * (sample(im, a.x(), a.y()) + sample(im, b.x(), b.y())) - sample(im, q.x(), q.y());
}

double median(std::vector<double>& v) {
  if (v.empty()) return 0.0;
  auto mid = v.begin() + static_cast<long>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

}  // namespace

LineEvidence line_evidence(const FloatImage& detection, std::span<const Eigen::Vector2i> pixels,
                           const LineEvidenceOptions& o) {
  LineEvidence e;
  if (pixels.size() < 2 || detection.width < 2 || detection.height < 2) return e;
  // The principal axis u (and n across it) of the pixels.
  Eigen::Vector2d c = Eigen::Vector2d::Zero();
  for (const auto& p : pixels) c += p.cast<double>();
  c /= static_cast<double>(pixels.size());
  Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
  for (const auto& p : pixels) {
    const Eigen::Vector2d d = p.cast<double>() - c;
    cov += d * d.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(cov);
  const Eigen::Vector2d u = eig.eigenvectors().col(1), n = eig.eigenvectors().col(0);
  // The centre curve: per unit step along u, the pixels' mean offset across.
  std::map<long, std::pair<double, int>> bins;
  double lo = 1e30, hi = -1e30;
  for (const auto& p : pixels) {
    const Eigen::Vector2d d = p.cast<double>() - c;
    const double a = d.dot(u);
    lo = std::min(lo, a), hi = std::max(hi, a);
    auto& b = bins[std::lround(a)];
    b.first += d.dot(n), b.second += 1;
  }
  e.length_px = hi - lo + 1.0;
  double across2 = 0.0;
  for (const auto& p : pixels) {
    const Eigen::Vector2d d = p.cast<double>() - c;
    const auto& b = bins[std::lround(d.dot(u))];
    const double off = d.dot(n) - b.first / b.second;
    across2 += off * off;
  }
  e.thickness_px = std::sqrt(across2 / static_cast<double>(pixels.size()));
  std::vector<double> along;
  for (const auto& [k, b] : bins) {
    const Eigen::Vector2d q = c + static_cast<double>(k) * u + (b.first / b.second) * n;
    along.push_back(second_difference(detection, q, n, o.offset_px));
  }
  e.samples = static_cast<int>(along.size());
  double sum = 0.0;
  for (const double v : along) sum += v;
  e.contrast = sum / e.samples;
  int same = 0;
  for (const double v : along) same += (v > 0) == (e.contrast > 0);
  e.consistency = static_cast<double>(same) / e.samples;
  // The noise: the second difference along u (flat along a groove) over the box grown by the
  // margin, its robust sd (1.4826 x the median absolute deviation).
  int x0 = detection.width, y0 = detection.height, x1 = -1, y1 = -1;
  for (const auto& p : pixels)
    x0 = std::min(x0, p.x()), y0 = std::min(y0, p.y()), x1 = std::max(x1, p.x()),
    y1 = std::max(y1, p.y());
  const int m = o.noise_margin_px;
  std::vector<double> noise;
  for (int y = std::max(0, y0 - m); y <= std::min(detection.height - 1, y1 + m); ++y)
    for (int x = std::max(0, x0 - m); x <= std::min(detection.width - 1, x1 + m); ++x)
      noise.push_back(second_difference(detection, Eigen::Vector2d(x, y), u, o.offset_px));
  const double mid = median(noise);
  for (auto& v : noise) v = std::abs(v - mid);
  e.noise = 1.4826 * median(noise);
  e.score = e.noise > 0 ? std::abs(e.contrast) / e.noise * std::sqrt(e.samples) : 0.0;
  // The continuation: the axis beyond the line's ends, one sample a pixel, inside the image.
  const double sign = e.contrast >= 0 ? 1.0 : -1.0;
  double cont = 0.0;
  for (int k = 1; k <= o.extend_px; ++k)
    for (const double a : {hi + k, lo - k}) {
      const Eigen::Vector2d q = c + a * u;
      if (q.x() < 0 || q.y() < 0 || q.x() > detection.width - 1 || q.y() > detection.height - 1)
        continue;
      cont += sign * second_difference(detection, q, n, o.offset_px);
      ++e.continuation_samples;
    }
  if (e.continuation_samples > 0) {
    e.continuation_contrast = cont / e.continuation_samples;
    e.continuation_score =
        e.noise > 0 ? e.continuation_contrast / e.noise * std::sqrt(e.continuation_samples) : 0.0;
  }
  return e;
}

}  // namespace fb
