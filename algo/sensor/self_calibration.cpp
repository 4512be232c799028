#include "algo/sensor/self_calibration.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>

#include <Eigen/Dense>

namespace fb {
namespace {

constexpr int kWidth = 640;
constexpr int kHeight = 480;
constexpr double kPi = 3.14159265358979323846;
constexpr double kCentreX = (kWidth - 1) / 2.0;
constexpr double kCentreY = (kHeight - 1) / 2.0;
constexpr float kGradientScale = 4.0f;  // stored gradients are grey levels per px x this
constexpr double kEdgeOffsetPx = 0.5;   // the contour lies half a pixel past the near pixel
constexpr double kInlierPx = 1.5;

struct Sample {
  float rx = 0, ry = 0;  // rectified colour position without any correction
  float parallax = 0;    // colour x shift at the sample's depth
  float nx = 0, ny = 0;  // unit normal towards the far side
};

struct Frame {
  std::vector<std::int16_t> gx, gy;  // colour gradient of the blurred grey image
  std::vector<Sample> samples;
};

struct Pose {
  double dx = 0, dy = 0, theta = 0;  // theta in radians
  // Where the colour edge lies along the normal from the near pixel's centre: half a pixel for
  // a sharp contour, more where the sensor drops a band of grazing surface before the contour.
  double bias = kEdgeOffsetPx;
};

Pose pose_of(const RegistrationCorrection& c) {
  return {c.dx_px, c.dy_px, c.rotation_deg * kPi / 180.0, kEdgeOffsetPx};
}

// Colour position of a sample under a registration pose (see RegistrationCorrection).
inline void position(const Sample& s, const Pose& p, double cs, double sn, double& x, double& y) {
  const double ux = s.rx - kCentreX, uy = s.ry - kCentreY;
  x = kCentreX + cs * ux - sn * uy + p.dx + s.parallax + p.bias * s.nx;
  y = kCentreY + sn * ux + cs * uy + p.dy + p.bias * s.ny;
}

// Gradient along the normal at a sub-pixel position (bilinear), in grey levels per px.
inline double normal_gradient(const Frame& f, double x, double y, double nx, double ny) {
  if (!(x >= 0.0 && y >= 0.0 && x < kWidth - 1 && y < kHeight - 1)) return 0.0;
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const double ax = x - x0, ay = y - y0;
  const std::size_t i = static_cast<std::size_t>(y0) * kWidth + x0;
  auto lerp = [&](const std::vector<std::int16_t>& g) {
    const double top = g[i] + ax * (g[i + 1] - g[i]);
    const double bottom = g[i + kWidth] + ax * (g[i + kWidth + 1] - g[i + kWidth]);
    return top + ay * (bottom - top);
  };
  return std::abs(nx * lerp(f.gx) + ny * lerp(f.gy)) / kGradientScale;
}

void compute_gradients(const ColorImage& color, std::vector<float>& grey,
                       std::vector<float>& blurred, Frame& f) {
  const std::size_t n = static_cast<std::size_t>(kWidth) * kHeight;
  grey.resize(n);
  blurred.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Rgb8 c = color.pixels[i];
    grey[i] = 0.299f * c.r + 0.587f * c.g + 0.114f * c.b;
  }
  // 3x3 binomial blur, then Sobel (normalised to grey levels per px).
  std::fill(blurred.begin(), blurred.end(), 0.0f);
  for (int y = 1; y < kHeight - 1; ++y)
    for (int x = 1; x < kWidth - 1; ++x) {
      const float* r0 = &grey[static_cast<std::size_t>(y - 1) * kWidth + x];
      const float* r1 = r0 + kWidth;
      const float* r2 = r1 + kWidth;
      blurred[static_cast<std::size_t>(y) * kWidth + x] =
          (r0[-1] + 2 * r0[0] + r0[1] + 2 * (r1[-1] + 2 * r1[0] + r1[1]) + r2[-1] + 2 * r2[0] +
           r2[1]) /
          16.0f;
    }
  f.gx.assign(n, 0);
  f.gy.assign(n, 0);
  auto clamp16 = [](float v) {
    return static_cast<std::int16_t>(std::clamp(std::lround(v * kGradientScale), -32000L, 32000L));
  };
  for (int y = 2; y < kHeight - 2; ++y)
    for (int x = 2; x < kWidth - 2; ++x) {
      const float* b = &blurred[static_cast<std::size_t>(y) * kWidth + x];
      const float gx =
          (b[-kWidth + 1] + 2 * b[1] + b[kWidth + 1] - b[-kWidth - 1] - 2 * b[-1] - b[kWidth - 1]) /
          8.0f;
      const float gy = (b[kWidth - 1] + 2 * b[kWidth] + b[kWidth + 1] - b[-kWidth - 1] -
                        2 * b[-kWidth] - b[-kWidth + 1]) /
                       8.0f;
      const std::size_t i = static_cast<std::size_t>(y) * kWidth + x;
      f.gx[i] = clamp16(gx);
      f.gy[i] = clamp16(gy);
    }
}

// Occluding contours on their near side: a measured pixel whose first measured neighbour in an
// axis direction (skipping up to max_gap unmeasured pixels) is farther by the jump threshold.
void find_edge_samples(const DepthImage& depth, const KinectRegistration& base,
                       const SelfCalibrationOptions& o, std::vector<Sample>& candidates,
                       std::vector<Sample>& out) {
  static constexpr std::array<std::array<int, 2>, 4> kDirections{
      {{1, 0}, {-1, 0}, {0, 1}, {0, -1}}};
  candidates.clear();
  const int b = std::max(o.border_px, 1);
  for (int y = b; y < kHeight - b; ++y)
    for (int x = b; x < kWidth - b; ++x) {
      const int z = depth.at(x, y);
      if (z == 0) continue;
      const double jump = std::max(o.min_jump_mm, o.min_jump_fraction * z);
      double nx = 0, ny = 0;
      for (const auto& d : kDirections) {
        for (int k = 1; k <= o.max_gap_px; ++k) {
          const int qx = x + k * d[0], qy = y + k * d[1];
          if (qx < 0 || qy < 0 || qx >= kWidth || qy >= kHeight) break;
          const int q = depth.at(qx, qy);
          if (q == 0) continue;
          if (q - z > jump) {
            nx += d[0];
            ny += d[1];
          }
          break;
        }
      }
      if (nx == 0 && ny == 0) continue;
      double rx = 0, ry = 0;
      if (!base.rectified_position(x, y, rx, ry)) continue;
      const double norm = std::hypot(nx, ny);
      candidates.push_back({static_cast<float>(rx), static_cast<float>(ry),
                            static_cast<float>(base.parallax_px(static_cast<std::uint16_t>(z))),
                            static_cast<float>(nx / norm), static_cast<float>(ny / norm)});
    }
  out.clear();
  if (candidates.empty()) return;
  const std::size_t keep = std::min<std::size_t>(candidates.size(), o.max_samples_per_frame);
  const double stride = static_cast<double>(candidates.size()) / static_cast<double>(keep);
  for (std::size_t i = 0; i < keep; ++i)
    out.push_back(candidates[static_cast<std::size_t>(i * stride)]);
}

}  // namespace

struct SelfCalibrator::Impl {
  KinectCalibration given;
  KinectRegistration base;  // the tables without any registration correction
  SelfCalibrationOptions o;
  std::vector<Frame> frames;
  int stored = 0;
  int stride = 1;  // every stride-th offered frame is used
  long long offered = 0;
  std::vector<float> grey, blurred;
  std::vector<Sample> candidates;

  Impl(const KinectCalibration& c, const SelfCalibrationOptions& options)
      : given(c), base(with_registration(c, RegistrationCorrection{})), o(options) {
    o.max_frames = std::max(2, o.max_frames);
    frames.resize(static_cast<std::size_t>(o.max_frames));
  }

  double coarse_score(const Pose& p, int frame_step, double cap) const;
  Pose coarse_search(double& distinctness) const;
  // Edge-to-edge refinement (ICP along normals); frames with index % modulo == remainder.
  Pose refine(Pose start, int modulo, int remainder, double* inlier_fraction,
              std::vector<double>* residuals) const;
};

SelfCalibrator::SelfCalibrator(const KinectCalibration& calibration, SelfCalibrationOptions options)
    : impl_(std::make_unique<Impl>(calibration, options)) {}
SelfCalibrator::~SelfCalibrator() = default;
SelfCalibrator::SelfCalibrator(SelfCalibrator&&) noexcept = default;
SelfCalibrator& SelfCalibrator::operator=(SelfCalibrator&&) noexcept = default;

void SelfCalibrator::add_frame(const DepthImage& depth_mm, const ColorImage& color) {
  Impl& s = *impl_;
  if (depth_mm.width != kWidth || depth_mm.height != kHeight || color.width != kWidth ||
      color.height != kHeight)
    return;
  if (s.offered++ % s.stride != 0) return;
  if (s.stored == s.o.max_frames) {
    // Keep every other frame so the stored ones still span the whole sequence.
    for (int i = 0; i < s.stored / 2; ++i) std::swap(s.frames[i], s.frames[2 * i]);
    s.stored /= 2;
    s.stride *= 2;
  }
  Frame& f = s.frames[static_cast<std::size_t>(s.stored)];
  find_edge_samples(depth_mm, s.base, s.o, s.candidates, f.samples);
  if (f.samples.empty()) return;
  compute_gradients(color, s.grey, s.blurred, f);
  ++s.stored;
}

void SelfCalibrator::clear() {
  impl_->stored = 0;
  impl_->stride = 1;
  impl_->offered = 0;
}

int SelfCalibrator::frames() const {
  return impl_->stored;
}

int SelfCalibrator::samples() const {
  int n = 0;
  for (int i = 0; i < impl_->stored; ++i) n += static_cast<int>(impl_->frames[i].samples.size());
  return n;
}

double SelfCalibrator::Impl::coarse_score(const Pose& p, int frame_step, double cap) const {
  const double cs = std::cos(p.theta), sn = std::sin(p.theta);
  double score = 0.0;
  for (int fi = 0; fi < stored; fi += frame_step) {
    const Frame& f = frames[static_cast<std::size_t>(fi)];
    for (const Sample& smp : f.samples) {
      double x = 0, y = 0;
      position(smp, p, cs, sn, x, y);
      const int xi = static_cast<int>(std::lround(x)), yi = static_cast<int>(std::lround(y));
      if (xi < 0 || yi < 0 || xi >= kWidth || yi >= kHeight) continue;
      const std::size_t i = static_cast<std::size_t>(yi) * kWidth + xi;
      const double g = std::abs(smp.nx * f.gx[i] + smp.ny * f.gy[i]) / kGradientScale;
      score += std::min(g, cap);
    }
  }
  return score;
}

Pose SelfCalibrator::Impl::coarse_search(double& distinctness) const {
  // At most about 12 frames: the coarse peak needs coverage, not every frame.
  const int frame_step = std::max(1, (stored + 11) / 12);
  const Pose centre = pose_of(given.correction);
  const int r = static_cast<int>(std::ceil(o.search_radius_px));
  const int side = 2 * r + 1;
  std::vector<double> grid(static_cast<std::size_t>(side) * side, 0.0);
  constexpr double kCap = 40.0;  // one strong texture edge must not outvote many contours
  for (int iy = 0; iy < side; ++iy)
    for (int ix = 0; ix < side; ++ix) {
      const Pose p{centre.dx + ix - r, centre.dy + iy - r, centre.theta, centre.bias};
      grid[static_cast<std::size_t>(iy) * side + ix] = coarse_score(p, frame_step, kCap);
    }
  const auto best_it = std::max_element(grid.begin(), grid.end());
  const int best = static_cast<int>(best_it - grid.begin());
  const int bx = best % side, by = best / side;
  double runner_up = 0.0;
  for (int iy = 0; iy < side; ++iy)
    for (int ix = 0; ix < side; ++ix)
      if (std::hypot(ix - bx, iy - by) > 4.0)
        runner_up = std::max(runner_up, grid[static_cast<std::size_t>(iy) * side + ix]);
  distinctness = runner_up > 0.0 ? *best_it / runner_up : (*best_it > 0.0 ? 10.0 : 1.0);
  // Sub-pixel by a parabola through the peak's neighbours in each axis.
  auto vertex = [](double a, double b, double c) {
    const double d = a - 2 * b + c;
    return d < 0.0 ? std::clamp(0.5 * (a - c) / d, -0.5, 0.5) : 0.0;
  };
  auto at = [&](int x, int y) {
    x = std::clamp(x, 0, side - 1);
    y = std::clamp(y, 0, side - 1);
    return grid[static_cast<std::size_t>(y) * side + x];
  };
  const double sx = vertex(at(bx - 1, by), at(bx, by), at(bx + 1, by));
  const double sy = vertex(at(bx, by - 1), at(bx, by), at(bx, by + 1));
  return {centre.dx + bx - r + sx, centre.dy + by - r + sy, centre.theta, centre.bias};
}

Pose SelfCalibrator::Impl::refine(Pose p, int modulo, int remainder, double* inlier_fraction,
                                  std::vector<double>* residuals) const {
  constexpr double kStep = 0.25;
  const double max_theta = o.max_rotation_deg * kPi / 180.0;
  int found = 0, total = 0, inliers = 0;
  for (int iteration = 0; iteration < 10; ++iteration) {
    const double window = iteration < 3 ? 4.0 : 2.0;
    const double cs = std::cos(p.theta), sn = std::sin(p.theta);
    Eigen::Matrix4d A = Eigen::Matrix4d::Zero();
    Eigen::Vector4d rhs = Eigen::Vector4d::Zero();
    found = total = inliers = 0;
    if (residuals) residuals->clear();
    for (int fi = 0; fi < stored; ++fi) {
      if (fi % modulo != remainder) continue;
      const Frame& f = frames[static_cast<std::size_t>(fi)];
      for (const Sample& smp : f.samples) {
        ++total;
        double x = 0, y = 0;
        position(smp, p, cs, sn, x, y);
        // The strongest colour edge along the normal within the window.
        double best = 0.0, best_t = 0.0, before = 0.0, after = 0.0, previous = 0.0;
        bool rising = false;
        for (double t = -window; t <= window + 1e-9; t += kStep) {
          const double g = normal_gradient(f, x + t * smp.nx, y + t * smp.ny, smp.nx, smp.ny);
          if (rising) after = g, rising = false;
          if (g > best) best = g, best_t = t, before = previous, rising = true;
          previous = g;
        }
        if (best < o.min_colour_gradient || std::abs(best_t) >= window) continue;
        const double d = before - 2 * best + after;
        const double t =
            best_t + (d < 0.0 ? std::clamp(0.5 * (before - after) / d, -0.5, 0.5) * kStep : 0.0);
        ++found;
        if (std::abs(t) < kInlierPx) ++inliers;
        if (residuals) residuals->push_back(std::abs(t));
        // Tukey weight on the offset: far matches are other edges.
        const double u = t / window;
        const double w = (1 - u * u) * (1 - u * u);
        const double ux = smp.rx - kCentreX, uy = smp.ry - kCentreY;
        const double jt = smp.nx * (-sn * ux - cs * uy) + smp.ny * (cs * ux - sn * uy);
        const Eigen::Vector4d J(smp.nx, smp.ny, jt, 1.0);
        rhs += w * t * J;
        A.noalias() += w * J * J.transpose();
      }
    }
    if (found < 12) break;
    // The rotation is weakly seen when the contours sit near the centre: a weak prior
    // (about 3 deg per sample) keeps it from wandering there.
    const double one_degree = kPi / 180.0;
    const double prior = 0.1 * found / (one_degree * one_degree);
    A(2, 2) += prior;
    // The edge bias is only seen through contours facing opposite ways; a prior (3 px) keeps
    // it bounded when they all face one way.
    const double bias_prior = found / 9.0;
    A(3, 3) += bias_prior;
    rhs[3] -= bias_prior * (p.bias - kEdgeOffsetPx);
    A(0, 0) += 1e-6;
    A(1, 1) += 1e-6;
    const Eigen::Vector4d step = A.ldlt().solve(rhs);
    if (!step.allFinite()) break;
    p.dx += step[0];
    p.dy += step[1];
    p.theta = std::clamp(p.theta + step[2], -max_theta, max_theta);
    p.bias = std::clamp(p.bias + step[3], -2.0, 8.0);
    if (iteration >= 3 && std::hypot(step[0], step[1]) < 0.01) break;
  }
  if (inlier_fraction) *inlier_fraction = total > 0 ? static_cast<double>(inliers) / total : 0.0;
  return p;
}

Result<SelfCalibrationResult> SelfCalibrator::estimate() const {
  const Impl& s = *impl_;
  SelfCalibrationResult r;
  r.frames = s.stored;
  r.samples = samples();
  if (s.stored == 0) {
    return fail(
        "self-calibration: no frame with depth edges was added; point the camera at a "
        "scene with objects in front of a background (a person, a chair)");
  }
  double distinctness = 1.0;
  Pose p = s.coarse_search(distinctness);
  double inlier_fraction = 0.0;
  std::vector<double> residuals;
  p = s.refine(p, 1, 0, &inlier_fraction, &residuals);
  // Two independent halves (alternate frames, or one frame's alternate samples would share
  // the image: use frames when there are two or more).
  Pose even = p, odd = p;
  if (s.stored >= 2) {
    even = s.refine(p, 2, 0, nullptr, nullptr);
    odd = s.refine(p, 2, 1, nullptr, nullptr);
  }
  RegistrationCorrection& c = r.correction;
  c = s.given.correction;
  c.dx_px = p.dx;
  c.dy_px = p.dy;
  c.rotation_deg = p.theta * 180.0 / kPi;
  RegistrationCorrection ce = c, co = c;
  ce.dx_px = even.dx, ce.dy_px = even.dy, ce.rotation_deg = even.theta * 180.0 / kPi;
  co.dx_px = odd.dx, co.dy_px = odd.dy, co.rotation_deg = odd.theta * 180.0 / kPi;
  r.halves_disagreement_px = registration_distance_px(ce, co);
  r.misregistration_px = registration_distance_px(c, s.given.correction);
  if (!residuals.empty()) {
    std::sort(residuals.begin(), residuals.end());
    r.residual_px = residuals[residuals.size() / 2];
    r.residual_px_p95 = residuals[std::min(residuals.size() - 1, residuals.size() * 95 / 100)];
  }
  const double agreement = std::exp(-std::pow(r.halves_disagreement_px / 1.5, 2));
  const double inliers = std::clamp(inlier_fraction / 0.4, 0.0, 1.0);
  const double peak = std::clamp((distinctness - 1.0) / 0.15, 0.0, 1.0);
  r.confidence = inliers * agreement * peak;
  if (r.samples < s.o.min_samples) {
    r.why = "only " + std::to_string(r.samples) + " depth-edge samples in " +
            std::to_string(r.frames) + " frames (need " + std::to_string(s.o.min_samples) +
            "); show the camera a person or objects in front of a background";
  } else if (r.confidence < s.o.ok_confidence) {
    char text[256];
    std::snprintf(text, sizeof text,
                  "the estimate is not reliable (confidence %.2f: %.0f %% of depth edges on colour "
                  "edges, halves of the frames disagree by %.1f px, peak ratio %.2f); record "
                  "frames with more depth edges, e.g. a person moving in front of a background",
                  r.confidence, 100.0 * inlier_fraction, r.halves_disagreement_px, distinctness);
    r.why = text;
  } else {
    r.ok = true;
  }
  return r;
}

KinectCalibration with_registration(const KinectCalibration& calibration,
                                    const RegistrationCorrection& registration) {
  KinectCalibration c = calibration;
  c.correction.dx_px = registration.dx_px;
  c.correction.dy_px = registration.dy_px;
  c.correction.rotation_deg = registration.rotation_deg;
  return c;
}

double registration_distance_px(const RegistrationCorrection& a, const RegistrationCorrection& b) {
  // The image centre and the centre of each quadrant: where faces are framed.
  static constexpr std::array<std::array<double, 2>, 5> kPoints{
      {{0, 0}, {-160, -120}, {160, -120}, {-160, 120}, {160, 120}}};
  const double ta = a.rotation_deg * kPi / 180.0, tb = b.rotation_deg * kPi / 180.0;
  double worst = 0.0;
  for (const auto& u : kPoints) {
    const double ax = std::cos(ta) * u[0] - std::sin(ta) * u[1] + a.dx_px;
    const double ay = std::sin(ta) * u[0] + std::cos(ta) * u[1] + a.dy_px;
    const double bx = std::cos(tb) * u[0] - std::sin(tb) * u[1] + b.dx_px;
    const double by = std::sin(tb) * u[0] + std::cos(tb) * u[1] + b.dy_px;
    worst = std::max(worst, std::hypot(ax - bx, ay - by));
  }
  return worst;
}
}  // namespace fb
