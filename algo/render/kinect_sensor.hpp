// Kinect v1 depth sensor model for synthetic scenes. Given a triangle mesh in the depth (IR)
// camera frame it renders the noiseless depth and then reproduces what the structured-light
// device would store:
//  - projector shadow: the IR projector sits dcmos_emitter_distance (7.5 cm) from the IR camera
//    along +x of the depth image (libfreenect's registration adds a shift that grows with depth
//    to x, i.e. the colour camera is on +x, and the projector lies beyond it on the same side:
//    front view "projector | RGB | IR"). A surface point the projector cannot see gets no
//    depth, so shadows fall on the -x (left) side of foreground objects, as on real Kinects;
//  - missing depth at depth discontinuities (the correlation window straddles two surfaces)
//    and at grazing angles (the speckle pattern is too stretched to match), both random near
//    the limit;
//  - Gaussian noise in disparity units followed by 11-bit quantisation, so depth noise grows
//    as z^2 (dz = z^2 / (f b) dd) and every output value is raw_to_mm of an integer raw.
// Pure: data in, data out; deterministic for a noise seed.
//
// Measured with the defaults (tests/render, tests/camera_synthetic): frontal plane mean abs
// error 1.51 mm at 0.7 m and 3.01 mm at 1.0 m (ratio 1.99, z^2 law 2.04); face pixels 1.53 mm
// at 0.7 m, 3.1 mm at 1.0 m. Holes on the face: 4-8 % (stated range 1-15 %), mostly grazing
// cheeks/jaw and silhouette edges, a little projector shadow beside the nose.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "algo/core/camera_model.hpp"
#include "algo/core/image.hpp"
#include "algo/core/result.hpp"
#include "algo/render/rasterizer.hpp"
#include "algo/sensor/kinect_calibration.hpp"

namespace fb {

struct KinectSensorOptions {
  // Gaussian disparity noise. sigma is in raw 11-bit units; the default is tuned so the mean
  // absolute depth error over a face at 0.7 m is about 1.5 mm (FaceWarehouse's raw figure).
  bool depth_noise = true;
  double disparity_noise_sigma = 1.3;
  // Projector shadow (deterministic geometry).
  bool projector_shadow = true;
  // Random dropouts at depth discontinuities and at grazing angles.
  bool dropouts = true;
  // Angle between the surface normal and the view ray: below `grazing_start_deg` always
  // measured, above `grazing_end_deg` never, linear probability in between.
  double grazing_start_deg = 72.0;
  double grazing_end_deg = 82.0;
  // A pixel is on a depth discontinuity when an 8-neighbour differs by more than
  // max(discontinuity_mm, discontinuity_fraction * z) or has no surface; such pixels are
  // dropped with `edge_drop_probability`.
  double discontinuity_mm = 15.0;
  double discontinuity_fraction = 0.02;
  double edge_drop_probability = 0.75;
  // Working range; outside it the device reports nothing.
  double min_depth_mm = 500.0;
  double max_depth_mm = 8000.0;
  // Disparity noise correlated over small blocks (the device matches 9x9 speckle windows, so
  // neighbouring pixels share their error): a Gaussian field drawn on a grid every
  // `correlated_noise_block_px` pixels, bilinearly interpolated, added to the per-pixel noise
  // before quantisation. Raw units; 0 = off (the default, so existing figures hold).
  double correlated_noise_sigma = 0.0;
  int correlated_noise_block_px = 6;
  // Low-rate speckle dropouts: isolated 2x2 holes where the pattern fails to match, with this
  // probability per 2x2 cell. 0 = off.
  double speckle_dropout_rate = 0.0;
};

// Why a pixel has no depth (bit mask, 0 = measured).
enum SensorInvalid : std::uint8_t {
  kSensorNoSurface = 1,
  kSensorOutOfRange = 2,
  kSensorProjectorShadow = 4,
  kSensorGrazing = 8,
  kSensorDepthEdge = 16,
  kSensorSpeckle = 32,   // speckle_dropout_rate
  kSensorMaterial = 64,  // hair or beard (set by the synthetic world, not by this model)
};

struct SensorFrame {
  DisparityImage raw;               // 11-bit disparity, kInvalidDisparity where missing
  DepthImage depth_mm;              // registration.raw_to_mm(raw), 0 where missing
  Image<float> noiseless_depth_mm;  // rendered z, 0 where no surface
  Image<std::uint8_t> invalid;      // SensorInvalid bits per pixel
};

class KinectSensorModel {
 public:
  // Builds the lookup tables (allocates); capture() then runs without allocation.
  KinectSensorModel(const KinectRegistration& registration, const KinectSensorOptions& options);

  const KinectSensorOptions& options() const { return options_; }
  const PinholeIntrinsics& intrinsics() const { return intrinsics_; }
  const KinectRegistration& registration() const { return registration_; }
  // IR camera to projector offset in the depth camera frame, mm (along +x).
  double projector_baseline_mm() const { return baseline_mm_; }

  // Renders `triangles` over `vertices` (depth camera frame, mm) and applies the sensor model.
  // `noise_seed` picks the noise and dropout pattern; the same seed gives identical output.
  Result<void> capture(std::span<const Eigen::Vector3f> vertices,
                       std::span<const std::uint32_t> triangles, std::uint64_t noise_seed,
                       SensorFrame& out);

  // The depth camera's raster of the last capture (triangle ids and barycentrics), e.g. for
  // shading a colour image.
  const RasterBuffers& camera_raster() const { return camera_; }

  // Continuous disparity for a depth: piecewise-linear inverse of raw_to_mm. Exposed for tests.
  double fractional_raw(double depth_mm) const;

 private:
  // The block-correlated part of the disparity noise at pixel (x, y), raw units.
  double correlated_noise(int x, int y, std::uint64_t noise_seed) const;
  // capture()'s stages: the depth camera's and the projector's rasters and the triangle
  // normals; why pixel (x, y) at `depth` (z: the noiseless depth) reads nothing (SensorInvalid
  // bits: range, projector shadow, depth edge, grazing angle, speckle); its disparity.
  Result<void> render_views(std::span<const Eigen::Vector3f> vertices,
                            std::span<const std::uint32_t> triangles);
  std::uint8_t invalid_bits(int x, int y, float depth, const Image<float>& z,
                            std::uint64_t noise_seed) const;
  bool projector_shadowed(int x, int y, float depth) const;
  std::uint8_t dropout_bits(int x, int y, float depth, const Image<float>& z,
                            std::uint64_t noise_seed) const;
  std::uint16_t raw_disparity(int x, int y, float depth, std::uint64_t noise_seed) const;

  KinectRegistration registration_;
  KinectSensorOptions options_;
  PinholeIntrinsics intrinsics_;
  PinholeIntrinsics projector_intrinsics_;
  double baseline_mm_ = 75.0;
  double cos_grazing_start_ = 1.0, cos_grazing_end_ = 0.0;  // of options_.grazing_*_deg
  int projector_pad_ = 0;
  std::vector<float> raw_of_mm_;       // fractional raw per integer mm
  std::vector<float> gaussian_table_;  // inverse normal CDF at (i + 0.5) / size
  std::vector<Eigen::Vector3f> projector_vertices_;
  std::vector<Eigen::Vector3f> triangle_normals_;
  RasterBuffers camera_;
  RasterBuffers projector_;
};

}  // namespace fb
