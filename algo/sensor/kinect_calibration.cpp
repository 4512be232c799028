// Kinect v1 disparity conversion and depth-to-colour registration.
//
// Reimplementation of libfreenect's src/registration.c (OpenKinect project, Apache-2.0 or
// GPL-2.0; https://github.com/OpenKinect/libfreenect/blob/master/src/registration.c):
//   freenect_raw_to_mm            -> raw_to_mm_value()
//   freenect_init_depth_to_rgb    -> build_depth_to_rgb_shift()
//   freenect_create_dxdy_tables   -> create_dxdy_tables()
//   freenect_init_registration_table -> build_registration_table()
//   freenect_apply_registration   -> KinectRegistration::register_depth_to_color()
//   freenect_camera_to_world      -> KinectCalibration::depth_intrinsics()
// The constants and the integer arithmetic (including the shift pairs that sign-extend the
// packed device fields) are kept exactly, so tables match libfreenect's bit for bit.
#include "algo/sensor/kinect_calibration.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>

namespace fb {
namespace {

// Constants from registration.c (current libfreenect master).
constexpr int kRegXValScale = 256;  // fixed-point scale of the x entries of the tables
constexpr double kS2dPixelConst = 10.0;
constexpr double kS2dConstOffset = 0.375;
constexpr int kDepthSensorXRes = 1280;       // the IR sensor's native width; images are 640 wide
constexpr int kDepthMaxMetricValue = 10000;  // mm; tables are indexed by mm below this
constexpr int kDepthMaxRawValue = 2048;
constexpr int kDepthXOffset = 1;
constexpr int kDepthYOffset = 1;
constexpr int kWidth = 640;
constexpr int kHeight = 480;
constexpr double kParameterCoefficient = 4.0;
constexpr double kShiftScale = 10.0;
constexpr double kPixelSizeFactor = 1.0;

// freenect_raw_to_mm, but returning the unclamped double so the caller decides what is valid.
double raw_to_mm_value(int raw, const KinectCalibration& c) {
  const auto& zpi = c.zero_plane_info;
  const double fixed_ref_x =
      ((raw - (kParameterCoefficient * c.const_shift / kPixelSizeFactor)) / kParameterCoefficient) -
      kS2dConstOffset;
  const double metric = fixed_ref_x * zpi.reference_pixel_size * kPixelSizeFactor;
  return kShiftScale * ((metric * zpi.reference_distance / (zpi.dcmos_emitter_distance - metric)) +
                        zpi.reference_distance);
}

// freenect_init_depth_to_rgb: horizontal shift (x kRegXValScale) of a depth pixel into the
// colour image as a function of its depth in mm (parallax over the IR-to-RGB baseline).
void build_depth_to_rgb_shift(const KinectZeroPlaneInfo& zpi, std::vector<std::int32_t>& out) {
  out.assign(kDepthMaxMetricValue, 0);
  const double x_scale = static_cast<double>(kDepthSensorXRes / kWidth);
  const double pixel_size = 1.0 / (zpi.reference_pixel_size * x_scale * kS2dPixelConst);
  const double pixels_between_rgb_and_ir_cmos =
      zpi.dcmos_rcmos_distance * pixel_size * kS2dPixelConst;
  const double reference_distance_in_pixels = zpi.reference_distance * pixel_size * kS2dPixelConst;
  // libfreenect also evaluates i = 0 (a division by zero); depth 0 is "invalid" and never
  // looked up, so it stays 0 here.
  for (int i = 1; i < kDepthMaxMetricValue; ++i) {
    const double current_depth_in_pixels = i * pixel_size;
    out[i] = static_cast<std::int32_t>(
        ((pixels_between_rgb_and_ir_cmos *
          (current_depth_in_pixels - reference_distance_in_pixels) / current_depth_in_pixels) +
         kS2dConstOffset) *
        kRegXValScale);
  }
}

// freenect_create_dxdy_tables: integrates the device's polynomial (forward differences in
// fixed point) into per-pixel x/y offsets. The field extraction relies on 32-bit wrap-around
// of left shifts followed by arithmetic right shifts (sign extension of packed fields); C++20
// defines both for signed integers, so the expressions are kept literally.
void create_dxdy_tables(const KinectRegInfo& r, std::vector<double>& reg_x,
                        std::vector<double>& reg_y) {
  const std::int64_t ax6 = r.ax, bx6 = r.bx, cx2 = r.cx, dx2 = r.dx;
  const std::int64_t ay6 = r.ay, by6 = r.by, cy2 = r.cy, dy2 = r.dy;

  std::int64_t dx0 = static_cast<std::int32_t>(r.dx_start << 13) >> 4;
  std::int64_t dy0 = static_cast<std::int32_t>(r.dy_start << 13) >> 4;

  std::int64_t dxdx0 = static_cast<std::int32_t>(r.dxdx_start << 11) >> 3;
  std::int64_t dxdy0 = static_cast<std::int32_t>(r.dxdy_start << 11) >> 3;
  std::int64_t dydx0 = static_cast<std::int32_t>(r.dydx_start << 11) >> 3;
  std::int64_t dydy0 = static_cast<std::int32_t>(r.dydy_start << 11) >> 3;

  std::int64_t dxdxdx0 =
      static_cast<std::int32_t>(static_cast<std::int32_t>(r.dxdxdx_start << 5) << 3);
  std::int64_t dydxdx0 =
      static_cast<std::int32_t>(static_cast<std::int32_t>(r.dydxdx_start << 5) << 3);
  std::int64_t dydxdy0 =
      static_cast<std::int32_t>(static_cast<std::int32_t>(r.dydxdy_start << 5) << 3);
  std::int64_t dxdxdy0 =
      static_cast<std::int32_t>(static_cast<std::int32_t>(r.dxdxdy_start << 5) << 3);
  std::int64_t dydydx0 =
      static_cast<std::int32_t>(static_cast<std::int32_t>(r.dydydx_start << 5) << 3);
  std::int64_t dydydy0 =
      static_cast<std::int32_t>(static_cast<std::int32_t>(r.dydydy_start << 5) << 3);

  reg_x.assign(static_cast<std::size_t>(kWidth) * kHeight, 0.0);
  reg_y.assign(static_cast<std::size_t>(kWidth) * kHeight, 0.0);
  std::size_t t = 0;
  for (int row = 0; row < kHeight; ++row) {
    dxdxdx0 += cx2;

    dxdx0 += dydxdx0 >> 8;
    dydxdx0 += dx2;

    dx0 += dydx0 >> 6;
    dydx0 += dydydx0 >> 8;
    dydydx0 += bx6;

    dxdxdy0 += cy2;

    dxdy0 += dydxdy0 >> 8;
    dydxdy0 += dy2;

    dy0 += dydy0 >> 6;
    dydy0 += dydydy0 >> 8;
    dydydy0 += by6;

    std::int64_t col_dxdxdy0 = dxdxdy0, col_dxdy0 = dxdy0, col_dy0 = dy0;
    std::int64_t col_dxdxdx0 = dxdxdx0, col_dxdx0 = dxdx0, col_dx0 = dx0;

    for (int col = 0; col < kWidth; ++col, ++t) {
      reg_x[t] = static_cast<double>(col_dx0) * (1.0 / (1 << 17));
      reg_y[t] = static_cast<double>(col_dy0) * (1.0 / (1 << 17));

      col_dx0 += col_dxdx0 >> 6;
      col_dxdx0 += col_dxdxdx0 >> 8;
      col_dxdxdx0 += ax6;

      col_dy0 += col_dxdy0 >> 6;
      col_dxdy0 += col_dxdxdy0 >> 8;
      col_dxdxdy0 += ay6;
    }
  }
}

// freenect_init_registration_table: per depth pixel, the rectified colour-image position
// before the depth-dependent parallax shift, x and y in fixed point (x kRegXValScale). The y of
// libfreenect's table is a truncated whole row; with an identity correction the values here are
// exactly libfreenect's. The unit's correction is applied on top (see RegistrationCorrection).
void build_registration_table(const KinectRegInfo& reg_info, const RegistrationCorrection& corr,
                              std::vector<std::int32_t>& table) {
  std::vector<double> dx;
  std::vector<double> dy;
  create_dxdy_tables(reg_info, dx, dy);
  table.assign(static_cast<std::size_t>(kWidth) * kHeight * 2, 0);
  const double angle = corr.rotation_deg * 3.14159265358979323846 / 180.0;
  const double cs = std::cos(angle), sn = std::sin(angle);
  const double cx = (kWidth - 1) / 2.0, cy = (kHeight - 1) / 2.0;
  const bool identity = corr.registration_is_identity();
  std::size_t index = 0;
  for (int y = 0; y < kHeight; ++y) {
    for (int x = 0; x < kWidth; ++x, ++index) {
      double new_x = x + dx[index] + kDepthXOffset;
      const double raw_y = y + dy[index] + kDepthYOffset;
      const bool inside = !(new_x < 0 || raw_y < 0 || new_x >= kWidth || raw_y >= kHeight);
      double new_y = static_cast<double>(static_cast<std::int32_t>(raw_y));  // C truncation
      if (!inside) {
        new_x = 2 * kWidth;  // deliberately outside the image, as libfreenect does
      } else if (!identity) {
        const double ux = new_x - cx, uy = new_y - cy;
        new_x = cx + cs * ux - sn * uy + corr.dx_px;
        new_y = cy + sn * ux + cs * uy + corr.dy_px;
      }
      table[2 * index] = static_cast<std::int32_t>(new_x * kRegXValScale);
      table[2 * index + 1] = static_cast<std::int32_t>(std::lround(new_y * kRegXValScale));
    }
  }
}

// Floor division by the fixed-point scale (the corrected table can hold negative y).
std::int32_t floor_fixed(std::int32_t v) {
  return v >= 0 ? v / kRegXValScale : -((-v + kRegXValScale - 1) / kRegXValScale);
}

}  // namespace

double RegistrationCorrection::corrected_mm(double table_mm) const {
  if (!(table_mm > 0.0)) return 0.0;
  if (depth_scale == 1.0 && inverse_depth_offset_per_m == 0.0) return table_mm;
  const double inverse = 1.0 / (depth_scale * table_mm) + inverse_depth_offset_per_m / 1000.0;
  return inverse > 0.0 ? 1.0 / inverse : 0.0;
}

KinectCalibration KinectCalibration::defaults() {
  // Values of the openiss-desk dump's device.json (a real Kinect v1, model 1414). The two
  // odd-looking decimals are the device's float32 values widened to double.
  KinectCalibration c;
  KinectRegInfo& r = c.reg_info;
  r.ax = 1830;
  r.bx = 11;
  r.cx = 31;
  r.dx = 497;
  r.ay = 56;
  r.by = 2582;
  r.cy = 641;
  r.dy = 77;
  r.dx_start = 3269;
  r.dy_start = 8447;
  r.dx_beta_start = 10062;
  r.dy_beta_start = 130801;
  r.dx_beta_inc = 170;
  r.dy_beta_inc = 136;
  r.dxdx_start = 2096139;
  r.dxdy_start = 1537;
  r.dydx_start = 8;
  r.dydy_start = 2096178;
  r.dxdxdx_start = 134215349;
  r.dydxdx_start = 134217225;
  r.dxdxdy_start = 134216993;
  r.dydxdy_start = 134216795;
  r.dydydx_start = 134217133;
  r.dydydy_start = 134215132;
  c.pad_info = KinectPadInfo{0, 0, 0};
  c.zero_plane_info.dcmos_emitter_distance = 7.5;
  c.zero_plane_info.dcmos_rcmos_distance = 2.4000000953674316;
  c.zero_plane_info.reference_distance = 120.0;
  c.zero_plane_info.reference_pixel_size = 0.10419999808073044;
  c.const_shift = 200;
  return c;
}

KinectCalibration KinectCalibration::typical_unit() {
  KinectCalibration c = defaults();
  c.correction.dy_px = -13.0;
  return c;
}

PinholeIntrinsics KinectCalibration::depth_intrinsics() const {
  // freenect_camera_to_world: wx = (x - 640/2) * 2 * reference_pixel_size * z /
  // reference_distance. The zero-plane pixel size is for the 1280-wide sensor, and the 640x480
  // image is that sensor cropped to 1280x960 and halved, hence the factor 2 in both axes.
  // The principal point is libfreenect's (320, 240), not the geometric centre (319.5, 239.5).
  PinholeIntrinsics k;
  k.width = kWidth;
  k.height = kHeight;
  k.fx = zero_plane_info.reference_distance / (2.0 * zero_plane_info.reference_pixel_size);
  k.fy = k.fx;
  k.cx = kWidth / 2.0;
  k.cy = kHeight / 2.0;
  return k;
}

KinectRegistration::KinectRegistration(const KinectCalibration& calibration)
    : calibration_(calibration) {
  // raw -> mm. libfreenect stores the truncated double in a uint16 (undefined beyond the
  // pole of the formula, around raw 1090); here anything not in (0, 10000) mm is invalid, which
  // is what its registration path treats as "no depth" anyway.
  raw_to_mm_table_.assign(kDepthMaxRawValue, 0);
  raw_to_mm_exact_table_.assign(kDepthMaxRawValue, 0.0f);
  for (int raw = 0; raw < kDepthMaxRawValue; ++raw) {
    const double table_mm = raw_to_mm_value(raw, calibration_);
    if (!std::isfinite(table_mm) || table_mm < 1.0) continue;
    const double mm = calibration_.correction.corrected_mm(table_mm);
    if (std::isfinite(mm) && mm >= 1.0 && mm < kDepthMaxMetricValue - 0.5) {
      raw_to_mm_table_[raw] = static_cast<std::uint16_t>(std::lround(mm));
      raw_to_mm_exact_table_[raw] = static_cast<float>(mm);
    }
  }
  raw_to_mm_table_[kInvalidDisparity] = 0;
  raw_to_mm_exact_table_[kInvalidDisparity] = 0.0f;

  // mm -> nearest raw. raw_to_mm is non-decreasing over the valid raw range (it is
  // z = b*f / (d0 - d) shaped), so one sweep with a moving cursor finds the nearest raw for
  // every mm. Depths outside [min, max] representable depth (by more than half a step) map
  // to kInvalidDisparity: the sensor cannot report them.
  int first_valid = -1;
  int last_valid = -1;
  for (int raw = 0; raw < kDepthMaxRawValue; ++raw) {
    if (raw_to_mm_table_[raw] == 0) continue;
    if (first_valid < 0) first_valid = raw;
    if (last_valid >= 0 && raw != last_valid + 1) break;  // keep the contiguous valid run
    last_valid = raw;
  }
  mm_to_raw_table_.assign(kDepthMaxMetricValue, kInvalidDisparity);
  if (first_valid >= 0) {
    const int min_mm = raw_to_mm_table_[first_valid];
    const int max_mm = raw_to_mm_table_[last_valid];
    const int first_step = first_valid < last_valid
                               ? raw_to_mm_table_[first_valid + 1] - raw_to_mm_table_[first_valid]
                               : 0;
    const int last_step = first_valid < last_valid
                              ? raw_to_mm_table_[last_valid] - raw_to_mm_table_[last_valid - 1]
                              : 0;
    int cursor = first_valid;
    for (int mm = 1; mm < kDepthMaxMetricValue; ++mm) {
      if (mm < min_mm - first_step / 2 || mm > max_mm + last_step / 2) continue;
      // Advance while the next raw is at least as close (ties and runs of equal mm values go to
      // the larger raw; either is a nearest raw).
      while (cursor < last_valid && std::abs(raw_to_mm_table_[cursor + 1] - mm) <=
                                        std::abs(raw_to_mm_table_[cursor] - mm)) {
        ++cursor;
      }
      mm_to_raw_table_[mm] = static_cast<std::uint16_t>(cursor);
    }
  }

  build_depth_to_rgb_shift(calibration_.zero_plane_info, depth_to_rgb_shift_);
  build_registration_table(calibration_.reg_info, calibration_.correction, registration_table_);
}

std::uint16_t KinectRegistration::raw_to_mm(std::uint16_t raw) const {
  return raw < raw_to_mm_table_.size() ? raw_to_mm_table_[raw] : 0;
}

float KinectRegistration::raw_to_mm_exact(std::uint16_t raw) const {
  return raw < raw_to_mm_exact_table_.size() ? raw_to_mm_exact_table_[raw] : 0.0f;
}

std::uint16_t KinectRegistration::mm_to_raw(std::uint16_t mm) const {
  return mm < mm_to_raw_table_.size() ? mm_to_raw_table_[mm] : kInvalidDisparity;
}

void KinectRegistration::disparity_to_mm(const DisparityImage& raw, DepthImage& out) const {
  if (out.width != raw.width || out.height != raw.height ||
      out.pixels.size() != raw.pixels.size()) {
    out.resize(raw.width, raw.height);
  }
  const std::uint16_t* table = raw_to_mm_table_.data();
  const std::size_t n = raw.pixels.size();
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint16_t r = raw.pixels[i];
    out.pixels[i] = r < kDepthMaxRawValue ? table[r] : 0;
  }
}

void KinectRegistration::mm_to_disparity(const DepthImage& mm, DisparityImage& out) const {
  if (out.width != mm.width || out.height != mm.height || out.pixels.size() != mm.pixels.size()) {
    out.resize(mm.width, mm.height);
  }
  const std::uint16_t* table = mm_to_raw_table_.data();
  const std::size_t n = mm.pixels.size();
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint16_t z = mm.pixels[i];
    out.pixels[i] = z < kDepthMaxMetricValue ? table[z] : kInvalidDisparity;
  }
}

bool KinectRegistration::depth_to_color(int x, int y, std::uint16_t mm, double& color_x,
                                        double& color_y) const {
  if (mm == 0 || mm >= kDepthMaxMetricValue) return false;
  if (!color_row(x, y, color_y)) return false;
  const std::size_t index = static_cast<std::size_t>(y) * kWidth + x;
  const std::int32_t fx = registration_table_[2 * index] + depth_to_rgb_shift_[mm];
  // Same pixel as libfreenect picks: it truncates fx / 256 (and stores y truncated), so the
  // colour pixel (floor(color_x), color_y) is the one register_depth_to_color() writes.
  color_x = static_cast<double>(fx) / kRegXValScale;
  return color_x >= 0.0 && color_x < kWidth;
}

bool KinectRegistration::depth_to_color_interpolated(double x, double y, double mm, double& color_x,
                                                     double& color_y) const {
  if (!(mm > 0.0 && mm < 65535.0) || !(x > -1.0 && y > -1.0 && x < kWidth && y < kHeight))
    return false;
  const auto z = static_cast<std::uint16_t>(mm + 0.5);
  if (z == 0 || z >= kDepthMaxMetricValue) return false;
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  const double fx = x - x0, fy = y - y0;
  // depth_to_color() at the four neighbours, its lookups inlined (the texture samples millions).
  const std::int32_t shift = depth_to_rgb_shift_[z];
  const double pad = calibration_.pad_info.start_lines;
  double sx = 0.0, sy = 0.0, weight = 0.0;
  for (int dy = 0; dy <= 1; ++dy) {
    for (int dx = 0; dx <= 1; ++dx) {
      const int u = x0 + dx, v = y0 + dy;
      if (u < 0 || v < 0 || u >= kWidth || v >= kHeight) continue;
      const std::size_t index = static_cast<std::size_t>(v) * kWidth + u;
      const double cy =
          static_cast<double>(registration_table_[2 * index + 1]) / kRegXValScale - pad;
      if (!(cy >= 0.0 && cy < kHeight)) continue;
      const double cx = static_cast<double>(registration_table_[2 * index] + shift) / kRegXValScale;
      if (!(cx >= 0.0 && cx < kWidth)) continue;
      const double w = (dx ? fx : 1.0 - fx) * (dy ? fy : 1.0 - fy) + 1e-9;
      sx += w * cx;
      sy += w * cy;
      weight += w;
    }
  }
  if (weight <= 0.0) return false;
  color_x = sx / weight;
  color_y = sy / weight;
  return true;
}

bool KinectRegistration::rectified_position(int x, int y, double& color_x, double& color_y) const {
  if (x < 0 || y < 0 || x >= kWidth || y >= kHeight) return false;
  const std::size_t index = static_cast<std::size_t>(y) * kWidth + x;
  if (registration_table_[2 * index] >= 2 * kWidth * kRegXValScale) return false;
  color_x = static_cast<double>(registration_table_[2 * index]) / kRegXValScale;
  color_y = static_cast<double>(registration_table_[2 * index + 1]) / kRegXValScale -
            calibration_.pad_info.start_lines;
  return true;
}

double KinectRegistration::parallax_px(std::uint16_t mm) const {
  if (mm == 0 || mm >= kDepthMaxMetricValue) return 0.0;
  return static_cast<double>(depth_to_rgb_shift_[mm]) / kRegXValScale;
}

bool KinectRegistration::color_row(int x, int y, double& color_y) const {
  if (x < 0 || y < 0 || x >= kWidth || y >= kHeight) return false;
  const std::size_t index = static_cast<std::size_t>(y) * kWidth + x;
  color_y = static_cast<double>(registration_table_[2 * index + 1]) / kRegXValScale -
            calibration_.pad_info.start_lines;
  return color_y >= 0.0 && color_y < kHeight;
}

void KinectRegistration::register_depth_to_color(const DepthImage& depth_mm,
                                                 DepthImage& registered) const {
  if (registered.width != depth_mm.width || registered.height != depth_mm.height ||
      registered.pixels.size() != depth_mm.pixels.size()) {
    registered.resize(depth_mm.width, depth_mm.height);
  }
  std::fill(registered.pixels.begin(), registered.pixels.end(), std::uint16_t{0});
  // The tables describe the 640x480 mode only; any other size has nothing that maps.
  if (depth_mm.width != kWidth || depth_mm.height != kHeight) return;

  // libfreenect subtracts DEPTH_Y_RES * start_lines from the linear index (a row/column mix-up
  // that is harmless because every known device reports start_lines = 0); shifting by whole
  // rows is what the padding means, so rows are shifted here.
  const int row_offset = calibration_.pad_info.start_lines;
  const std::int32_t* table = registration_table_.data();
  const std::int32_t* shift = depth_to_rgb_shift_.data();
  std::uint16_t* out = registered.pixels.data();
  const std::uint16_t* in = depth_mm.pixels.data();
  std::size_t index = 0;
  for (int y = 0; y < kHeight; ++y) {
    for (int x = 0; x < kWidth; ++x, ++index) {
      const std::uint16_t metric_depth = in[index];
      if (metric_depth == 0 || metric_depth >= kDepthMaxMetricValue) continue;
      // Integer division truncates toward zero exactly like the C original.
      const std::int32_t nx = (table[2 * index] + shift[metric_depth]) / kRegXValScale;
      const std::int32_t ny = floor_fixed(table[2 * index + 1]) - row_offset;
      if (nx < 0 || nx >= kWidth || ny < 0 || ny >= kHeight) continue;
      std::uint16_t& target = out[static_cast<std::size_t>(ny) * kWidth + nx];
      // Nearest surface wins where several depth pixels land on the same colour pixel.
      if (target == 0 || target > metric_depth) target = metric_depth;
    }
  }
}

}  // namespace fb
