#include "algo/render/kinect_sensor.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "algo/core/mix64.hpp"

namespace fb {
namespace {

std::uint64_t pixel_random(std::uint64_t seed, std::size_t pixel, std::uint64_t stream) {
  return mix64(seed ^ mix64((static_cast<std::uint64_t>(pixel) << 8) | stream));
}

double unit_uniform(std::uint64_t bits) {
  return static_cast<double>(bits >> 11) * 0x1.0p-53;
}

// Inverse standard normal CDF (Acklam's rational approximation, relative error < 1.2e-9).
double inverse_normal_cdf(double p) {
  static constexpr double a[] = {-3.969683028665376e+01, 2.209460984245205e+02,
                                 -2.759285104469687e+02, 1.383577518672690e+02,
                                 -3.066479806614716e+01, 2.506628277459239e+00};
  static constexpr double b[] = {-5.447609879822406e+01, 1.615858368580409e+02,
                                 -1.556989798598866e+02, 6.680131188771972e+01,
                                 -1.328068155288572e+01};
  static constexpr double c[] = {-7.784894002430293e-03, -3.223964580411365e-01,
                                 -2.400758277161838e+00, -2.549732539343734e+00,
                                 4.374664141464968e+00,  2.938163982698783e+00};
  static constexpr double d[] = {7.784695709041462e-03, 3.224671290700398e-01,
                                 2.445134137142996e+00, 3.754408661907416e+00};
  constexpr double p_low = 0.02425;
  if (p < p_low) {
    const double q = std::sqrt(-2.0 * std::log(p));
    return (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
           ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1.0);
  }
  if (p > 1.0 - p_low) return -inverse_normal_cdf(1.0 - p);
  const double q = p - 0.5;
  const double r = q * q;
  return (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) * q /
         (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1.0);
}

constexpr std::size_t kGaussianTableBits = 16;
constexpr std::uint64_t kStreamNoise = 1, kStreamEdge = 2, kStreamGrazing = 3,
                        kStreamCorrelated = 4, kStreamSpeckle = 5;

}  // namespace

KinectSensorModel::KinectSensorModel(const KinectRegistration& registration,
                                     const KinectSensorOptions& options)
    : registration_(registration), options_(options) {
  intrinsics_ = registration_.depth_intrinsics();
  baseline_mm_ = registration_.calibration().zero_plane_info.dcmos_emitter_distance * 10.0;
  cos_grazing_start_ = std::cos(options_.grazing_start_deg * std::numbers::pi / 180.0);
  cos_grazing_end_ = std::cos(options_.grazing_end_deg * std::numbers::pi / 180.0);
  // The projector looks along +z from (b, 0, 0); a point at depth z seen at column u lands in
  // projector column u - f b / z, so pad the projector image on the left for the nearest depth.
  projector_pad_ =
      static_cast<int>(std::ceil(intrinsics_.fx * baseline_mm_ / options_.min_depth_mm)) + 2;
  projector_intrinsics_ = intrinsics_;
  projector_intrinsics_.width = intrinsics_.width + projector_pad_;
  projector_intrinsics_.cx = intrinsics_.cx + projector_pad_;

  // Continuous disparity: raw_to_mm is monotonic over the valid range; average the raws that
  // round to the same millimetre, then interpolate linearly between those knots.
  constexpr int kMaxMm = 10000;
  std::vector<double> raw_sum(kMaxMm + 1, 0.0);
  std::vector<int> raw_count(kMaxMm + 1, 0);
  for (int raw = 0; raw < kInvalidDisparity; ++raw) {
    const int mm = registration_.raw_to_mm(static_cast<std::uint16_t>(raw));
    if (mm <= 0 || mm > kMaxMm) continue;
    raw_sum[mm] += raw;
    ++raw_count[mm];
  }
  raw_of_mm_.assign(kMaxMm + 1, -1.0f);
  int previous = -1;
  for (int mm = 0; mm <= kMaxMm; ++mm) {
    if (raw_count[mm] == 0) continue;
    const double raw = raw_sum[mm] / raw_count[mm];
    raw_of_mm_[mm] = static_cast<float>(raw);
    if (previous >= 0) {
      const double raw0 = raw_of_mm_[previous];
      for (int m = previous + 1; m < mm; ++m) {
        raw_of_mm_[m] = static_cast<float>(raw0 + (raw - raw0) * (m - previous) / (mm - previous));
      }
    }
    previous = mm;
  }

  gaussian_table_.resize(std::size_t{1} << kGaussianTableBits);
  for (std::size_t i = 0; i < gaussian_table_.size(); ++i) {
    gaussian_table_[i] = static_cast<float>(inverse_normal_cdf(
        (static_cast<double>(i) + 0.5) / static_cast<double>(gaussian_table_.size())));
  }
}

double KinectSensorModel::correlated_noise(int x, int y, std::uint64_t noise_seed) const {
  if (options_.correlated_noise_sigma <= 0.0) return 0.0;
  // Gaussian values on a coarse grid, bilinearly interpolated: neighbours within a block share
  // most of their error, as the device's window matching makes them.
  const int b = std::max(1, options_.correlated_noise_block_px);
  const int gx = x / b, gy = y / b;
  const double fx = static_cast<double>(x - gx * b) / b, fy = static_cast<double>(y - gy * b) / b;
  const std::size_t table_mask = gaussian_table_.size() - 1;
  const std::size_t stride = static_cast<std::size_t>(intrinsics_.width / b + 2);
  auto node = [&](int ix, int iy) {
    const std::size_t k = static_cast<std::size_t>(iy) * stride + static_cast<std::size_t>(ix);
    return static_cast<double>(
        gaussian_table_[(pixel_random(noise_seed, k, kStreamCorrelated) >> 20) & table_mask]);
  };
  const double v = (1 - fx) * (1 - fy) * node(gx, gy) + fx * (1 - fy) * node(gx + 1, gy) +
                   (1 - fx) * fy * node(gx, gy + 1) + fx * fy * node(gx + 1, gy + 1);
  // Bilinear blending shrinks the variance (to 4/9 at a block's centre); 1.5 restores about
  // the nominal sigma on average over a block.
  return 1.5 * options_.correlated_noise_sigma * v;
}

double KinectSensorModel::fractional_raw(double depth_mm) const {
  if (!(depth_mm >= 0.0) || depth_mm >= static_cast<double>(raw_of_mm_.size() - 1)) return -1.0;
  const auto lo = static_cast<std::size_t>(depth_mm);
  const double r0 = raw_of_mm_[lo], r1 = raw_of_mm_[lo + 1];
  if (r0 < 0.0 || r1 < 0.0) return -1.0;
  return r0 + (r1 - r0) * (depth_mm - static_cast<double>(lo));
}

Result<void> KinectSensorModel::render_views(std::span<const Eigen::Vector3f> vertices,
                                             std::span<const std::uint32_t> triangles) {
  camera_.reset(intrinsics_.width, intrinsics_.height);
  RasterOptions raster;
  if (auto drawn = rasterize(intrinsics_, vertices, triangles, raster, camera_); !drawn) {
    return drawn.failure();
  }
  if (options_.projector_shadow) {
    projector_vertices_.resize(vertices.size());
    const Eigen::Vector3f offset(static_cast<float>(baseline_mm_), 0.0f, 0.0f);
    for (std::size_t i = 0; i < vertices.size(); ++i) projector_vertices_[i] = vertices[i] - offset;
    projector_.reset(projector_intrinsics_.width, projector_intrinsics_.height);
    if (auto drawn =
            rasterize(projector_intrinsics_, projector_vertices_, triangles, raster, projector_);
        !drawn) {
      return drawn.failure();
    }
  }

  // Unit normal per triangle, for the grazing-angle test.
  const std::size_t triangle_count = triangles.size() / 3;
  triangle_normals_.resize(triangle_count);
  for (std::size_t t = 0; t < triangle_count; ++t) {
    const Eigen::Vector3f& a = vertices[triangles[3 * t]];
    const Eigen::Vector3f n =
        (vertices[triangles[3 * t + 1]] - a).cross(vertices[triangles[3 * t + 2]] - a);
    const float length = n.norm();
    triangle_normals_[t] = length > 0.0f ? Eigen::Vector3f(n / length) : Eigen::Vector3f::Zero();
  }
  return success();
}

inline bool KinectSensorModel::projector_shadowed(int x, int y, float depth) const {
  // Same rows and same z in the projector frame (pure x offset); the true sample lies
  // between two projector columns, so compare with the farther of the two.
  const double up = x - intrinsics_.fx * baseline_mm_ / depth + projector_pad_;
  const int u0 = static_cast<int>(std::floor(up));
  float visible_z = 0.0f;
  for (int u = u0; u <= u0 + 1; ++u) {
    if (u >= 0 && u < projector_.width) {
      visible_z = std::max(visible_z, projector_.depth[projector_.index(u, y)]);
    }
  }
  return depth > visible_z + 1.0f + 0.002f * depth;
}

inline std::uint8_t KinectSensorModel::dropout_bits(int x, int y, float depth,
                                                    const Image<float>& z,
                                                    std::uint64_t noise_seed) const {
  const int w = intrinsics_.width, h = intrinsics_.height;
  const std::size_t i = camera_.index(x, y);
  std::uint8_t invalid = 0;
  // Depth discontinuity: any 8-neighbour on another surface (or none).
  const float threshold = std::max(static_cast<float>(options_.discontinuity_mm),
                                   static_cast<float>(options_.discontinuity_fraction) * depth);
  bool edge = false;
  for (int dy = -1; dy <= 1 && !edge; ++dy) {
    for (int dx = -1; dx <= 1; ++dx) {
      const int nx = x + dx, ny = y + dy;
      if (nx < 0 || ny < 0 || nx >= w || ny >= h) continue;
      const float n = z.pixels[camera_.index(nx, ny)];
      if (n <= 0.0f || std::abs(n - depth) > threshold) {
        edge = true;
        break;
      }
    }
  }
  if (edge &&
      unit_uniform(pixel_random(noise_seed, i, kStreamEdge)) < options_.edge_drop_probability) {
    invalid |= kSensorDepthEdge;
  }

  // Grazing angle between the visible triangle's normal and the view ray.
  const double cos_start = cos_grazing_start_, cos_end = cos_grazing_end_;
  const Eigen::Vector3f& normal = triangle_normals_[static_cast<std::size_t>(camera_.triangle[i])];
  const Eigen::Vector3f ray((x - intrinsics_.cx) / intrinsics_.fx,
                            (y - intrinsics_.cy) / intrinsics_.fy, 1.0f);
  const double cos_angle = std::abs(normal.dot(ray)) / static_cast<double>(ray.norm());
  if (cos_angle < cos_start) {
    // p(drop) rises linearly from 0 at grazing_start to 1 at grazing_end (in angle).
    const double angle = std::acos(std::clamp(cos_angle, 0.0, 1.0)) * 180.0 / std::numbers::pi;
    const double p = (angle - options_.grazing_start_deg) /
                     (options_.grazing_end_deg - options_.grazing_start_deg);
    if (cos_angle <= cos_end || unit_uniform(pixel_random(noise_seed, i, kStreamGrazing)) < p) {
      invalid |= kSensorGrazing;
    }
  }
  return invalid;
}

inline std::uint8_t KinectSensorModel::invalid_bits(int x, int y, float depth,
                                                    const Image<float>& z,
                                                    std::uint64_t noise_seed) const {
  std::uint8_t invalid = 0;
  if (depth <= 0.0f) {
    invalid = kSensorNoSurface;
  } else if (depth < options_.min_depth_mm || depth > options_.max_depth_mm) {
    invalid = kSensorOutOfRange;
  }
  if (invalid == 0 && options_.projector_shadow && projector_shadowed(x, y, depth))
    invalid |= kSensorProjectorShadow;
  if (invalid == 0 && options_.dropouts) invalid |= dropout_bits(x, y, depth, z, noise_seed);
  if (invalid == 0 && options_.speckle_dropout_rate > 0.0) {
    const std::size_t cell =
        static_cast<std::size_t>(y / 2) * static_cast<std::size_t>(intrinsics_.width) +
        static_cast<std::size_t>(x / 2);
    if (unit_uniform(pixel_random(noise_seed, cell, kStreamSpeckle)) <
        options_.speckle_dropout_rate)
      invalid |= kSensorSpeckle;
  }
  return invalid;
}

inline std::uint16_t KinectSensorModel::raw_disparity(int x, int y, float depth,
                                                      std::uint64_t noise_seed) const {
  if (!options_.depth_noise)
    return registration_.mm_to_raw(static_cast<std::uint16_t>(static_cast<double>(depth) + 0.5));
  // Noise in disparity units, then the device's integer quantisation.
  const double r = fractional_raw(depth);
  if (r < 0.0) return kInvalidDisparity;
  const std::size_t table_mask = gaussian_table_.size() - 1;
  const auto bits = pixel_random(noise_seed, camera_.index(x, y), kStreamNoise);
  const double noisy = r +
                       options_.disparity_noise_sigma * gaussian_table_[(bits >> 20) & table_mask] +
                       correlated_noise(x, y, noise_seed);
  // floor(x + 0.5): round half up, far cheaper than lround and the same for x >= 0.
  const long rounded = static_cast<long>(std::floor(noisy + 0.5));
  if (rounded >= 0 && rounded < kInvalidDisparity) return static_cast<std::uint16_t>(rounded);
  return kInvalidDisparity;
}

Result<void> KinectSensorModel::capture(std::span<const Eigen::Vector3f> vertices,
                                        std::span<const std::uint32_t> triangles,
                                        std::uint64_t noise_seed, SensorFrame& out) {
  const int w = intrinsics_.width, h = intrinsics_.height;
  if (auto drawn = render_views(vertices, triangles); !drawn) return drawn.failure();

  out.raw.resize(w, h);
  out.depth_mm.resize(w, h);
  out.noiseless_depth_mm.resize(w, h);
  out.invalid.resize(w, h);
  for (std::size_t i = 0; i < camera_.depth.size(); ++i) {
    out.noiseless_depth_mm.pixels[i] = camera_.triangle[i] == kNoTriangle ? 0.0f : camera_.depth[i];
  }

  const auto& z = out.noiseless_depth_mm;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const std::size_t i = camera_.index(x, y);
      const float depth = z.pixels[i];
      std::uint8_t invalid = invalid_bits(x, y, depth, z, noise_seed);
      std::uint16_t raw = invalid == 0 ? raw_disparity(x, y, depth, noise_seed) : kInvalidDisparity;
      std::uint16_t mm = raw == kInvalidDisparity ? 0 : registration_.raw_to_mm(raw);
      if (mm == 0) {
        raw = kInvalidDisparity;
        if (invalid == 0) invalid = kSensorOutOfRange;
      }
      out.raw.pixels[i] = raw;
      out.depth_mm.pixels[i] = mm;
      out.invalid.pixels[i] = invalid;
    }
  }
  return success();
}

}  // namespace fb
