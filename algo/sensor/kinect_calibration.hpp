// Kinect v1 calibration: raw 11-bit disparity <-> millimetres and depth-to-colour
// registration, computed in the project because Debian's fakenect lacks libfreenect's
// registration symbols and its mm/registered depth modes.
//
// The maths follows libfreenect's registration.c (Apache-2.0/GPL-2.0 dual licensed,
// reimplemented here): the device's reg_info polynomial gives a per-pixel distortion
// table, zero_plane_info gives the disparity-to-depth law and the depth-to-colour shift.
#pragma once

#include <cstdint>
#include <vector>

#include "algo/core/camera_model.hpp"
#include "algo/core/image.hpp"

namespace fb {

// Field names and meaning as in libfreenect's freenect_reg_info.
struct KinectRegInfo {
  std::int32_t ax = 0, bx = 0, cx = 0, dx = 0;
  std::int32_t ay = 0, by = 0, cy = 0, dy = 0;
  std::int32_t dx_start = 0, dy_start = 0;
  std::int32_t dx_beta_start = 0, dy_beta_start = 0;
  std::int32_t dx_beta_inc = 0, dy_beta_inc = 0;
  std::int32_t dxdx_start = 0, dxdy_start = 0, dydx_start = 0, dydy_start = 0;
  std::int32_t dxdxdx_start = 0, dydxdx_start = 0, dxdxdy_start = 0;
  std::int32_t dydxdy_start = 0, dydydx_start = 0, dydydy_start = 0;
};

struct KinectPadInfo {
  std::int32_t start_lines = 0;
  std::int32_t end_lines = 0;
  std::int32_t cropping_lines = 0;
};

// Lengths in centimetres / millimetres exactly as the device reports them.
struct KinectZeroPlaneInfo {
  double dcmos_emitter_distance = 7.5;   // cm, IR camera to projector baseline
  double dcmos_rcmos_distance = 2.4;     // cm, IR camera to colour camera
  double reference_distance = 120.0;     // mm, zero-plane distance
  double reference_pixel_size = 0.1042;  // mm, zero-plane pixel size (at 1280 width)
};

// What one unit differs by from the tables its firmware (or the defaults) describe, estimated
// by `camera calibrate` (checkerboard) or by self-calibration from ordinary frames.
//  - Registration: the rectified colour position of a depth pixel (the reg_info table) is
//    rotated by `rotation_deg` about the colour image centre and shifted by (dx_px, dy_px);
//    the depth-dependent parallax stays along the colour image's x axis, so a depth pixel's
//    colour row still does not depend on its depth.
//  - Depth law (Herrera et al. 2012, affine in disparity, i.e. in inverse depth):
//    1 / z = 1 / (depth_scale * z_table) + inverse_depth_offset_per_m / 1000, z in mm.
struct RegistrationCorrection {
  double dx_px = 0.0;
  double dy_px = 0.0;
  double rotation_deg = 0.0;
  double depth_scale = 1.0;
  double inverse_depth_offset_per_m = 0.0;

  bool is_identity() const {
    return dx_px == 0.0 && dy_px == 0.0 && rotation_deg == 0.0 && depth_scale == 1.0 &&
           inverse_depth_offset_per_m == 0.0;
  }
  bool registration_is_identity() const {
    return dx_px == 0.0 && dy_px == 0.0 && rotation_deg == 0.0;
  }
  // The corrected depth of a table depth (mm, not rounded); 0 stays 0.
  double corrected_mm(double table_mm) const;
};

struct KinectCalibration {
  KinectRegInfo reg_info;
  KinectPadInfo pad_info;
  KinectZeroPlaneInfo zero_plane_info;
  std::int32_t const_shift = 200;
  RegistrationCorrection correction;

  // Documented defaults: the values read from a real Kinect v1 (model 1414) as stored in
  // the openiss-desk dump's device.json. Used when neither a device nor a device.json is at hand.
  static KinectCalibration defaults();
  // The best guess for a unit nothing is known about (a recording without device.json, an
  // OpenNI2 device): the defaults' tables with the registration moved 13 rows up. The openiss
  // unit sits at the high end of the units surveyed in docs/registration-systematics.md
  // (colour row of the depth centre 252-268, 257 +- 6 across nine units and calibrations);
  // three real recordings needed -13 to -15. Self-calibration refines it per unit.
  static KinectCalibration typical_unit();

  // Pinhole model of the depth camera implied by zero_plane_info (f = reference_distance /
  // (2 * reference_pixel_size) at 640x480, about 575.8 px; principal point (320, 240) exactly as
  // libfreenect's freenect_camera_to_world uses it).
  PinholeIntrinsics depth_intrinsics() const;
};

// Precomputed tables for one calibration. Build once (allocates), then use per frame
// without allocation.
class KinectRegistration {
 public:
  explicit KinectRegistration(const KinectCalibration& calibration);

  const KinectCalibration& calibration() const { return calibration_; }
  PinholeIntrinsics depth_intrinsics() const { return calibration_.depth_intrinsics(); }

  // Raw 11-bit value -> millimetres, rounded to the nearest mm (0 for invalid/out-of-range raw
  // values). Rounding, not libfreenect's truncation: truncation biases every depth 0.5 mm
  // towards the camera.
  std::uint16_t raw_to_mm(std::uint16_t raw) const;
  // The same without rounding, for consumers that keep sub-millimetre depth (0 when invalid).
  float raw_to_mm_exact(std::uint16_t raw) const;
  // Millimetres -> the raw value whose depth is nearest (kInvalidDisparity for 0 or unreachable).
  std::uint16_t mm_to_raw(std::uint16_t mm) const;

  // Whole-image conversions; `out` is resized only when its size differs.
  void disparity_to_mm(const DisparityImage& raw, DepthImage& out) const;
  void mm_to_disparity(const DepthImage& mm, DisparityImage& out) const;

  // Where a depth pixel (x, y) with depth `mm` lands in the colour image. Returns false when
  // the depth is invalid or the target is outside the colour image. color_x and color_y have
  // 1/256 px resolution (color_y is a whole row under an identity correction, as in
  // libfreenect's table); the colour pixel (floor(color_x), floor(color_y)) is the one
  // register_depth_to_color() writes.
  bool depth_to_color(int x, int y, std::uint16_t mm, double& color_x, double& color_y) const;
  // depth_to_color() at a sub-pixel depth position: the four neighbouring pixels' colour
  // positions (at `mm` rounded) blended bilinearly. False where none of them maps.
  bool depth_to_color_interpolated(double x, double y, double mm, double& color_x,
                                   double& color_y) const;
  // The parts of depth_to_color(): the rectified colour position of a depth pixel before the
  // parallax (with the unit's correction) and the parallax along x at depth `mm`. False as
  // depth_to_color() when the pixel has no table entry.
  bool rectified_position(int x, int y, double& color_x, double& color_y) const;
  double parallax_px(std::uint16_t mm) const;
  // The colour row depth_to_color() gives for this pixel at any valid depth: the registration
  // shifts along x only. False outside the depth image or when that row is outside the colour
  // image.
  bool color_row(int x, int y, double& color_y) const;

  // Equivalent of libfreenect's FREENECT_DEPTH_REGISTERED: depth resampled into the colour
  // camera's image, nearest surface wins, 0 where nothing maps.
  // `registered` must not be `depth_mm` (it is cleared first).
  void register_depth_to_color(const DepthImage& depth_mm, DepthImage& registered) const;

 private:
  KinectCalibration calibration_;
  std::vector<std::uint16_t> raw_to_mm_table_;    // 2048 entries
  std::vector<float> raw_to_mm_exact_table_;      // 2048 entries
  std::vector<std::uint16_t> mm_to_raw_table_;    // up to 10000 mm
  std::vector<std::int32_t> depth_to_rgb_shift_;  // per mm, as in libfreenect
  // 640*480*2: per pixel the rectified colour x and y before the parallax shift, both in
  // 1/256 px, with the unit's correction applied (libfreenect's exact table when it is identity).
  std::vector<std::int32_t> registration_table_;
};

}  // namespace fb
