#include "algo/landmarks/landmark_lifting.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

namespace fb {

Image<float> depth_to_float(const DepthImage& depth_mm) {
  Image<float> out;
  out.resize(depth_mm.width, depth_mm.height);
  for (std::size_t i = 0; i < depth_mm.pixels.size(); ++i) out.pixels[i] = depth_mm.pixels[i];
  return out;
}

namespace {

// Both depth representations (float mm for fitting, the raw 16-bit frame for the tracker) go
// through the same code; 0 is "no measurement" in both.
template <class Pixel>
std::optional<Eigen::Vector2d> map_to_depth_pixel(const Eigen::Vector2d& color_px,
                                                  const Image<Pixel>& depth_mm,
                                                  const KinectRegistration& registration,
                                                  double reference_mm, const LiftOptions& options) {
  const int w = depth_mm.width, h = depth_mm.height;
  const auto ref16 = static_cast<std::uint16_t>(std::clamp(reference_mm, 1.0, 9999.0));
  auto mapped = [&](int x, int y, Eigen::Vector2d& c) {
    std::uint16_t mm = ref16;
    if (depth_mm.contains(x, y)) {
      const auto d = static_cast<float>(depth_mm.at(x, y));
      if (d > 0.0f && std::abs(d - reference_mm) <= options.depth_band_mm)
        mm = static_cast<std::uint16_t>(std::lround(d));
    }
    double cx = 0, cy = 0;
    if (!registration.depth_to_color(x, y, mm, cx, cy)) return false;
    c = {cx, cy};
    return true;
  };
  // First guess: the registration shift at the reference depth is nearly constant locally.
  int gx = std::clamp(static_cast<int>(std::lround(color_px.x())), 0, w - 1);
  int gy = std::clamp(static_cast<int>(std::lround(color_px.y())), 0, h - 1);
  for (int pass = 0; pass < 2; ++pass) {
    Eigen::Vector2d c;
    if (!mapped(gx, gy, c)) break;
    gx = std::clamp(static_cast<int>(std::lround(gx + color_px.x() - c.x())), 0, w - 1);
    gy = std::clamp(static_cast<int>(std::lround(gy + color_px.y() - c.y())), 0, h - 1);
  }
  // The pixel of the window that maps nearest to color_px; ties go to the first in raster
  // order. The registration shifts along x only (a pixel's colour row does not depend on its
  // depth), so a pixel whose row alone is farther than the best so far is passed over without
  // reading its depth; scanning in rings from the first guess outwards finds a close match
  // first, and the rest of the window mostly costs one table read a pixel.
  double best = 1e30;
  Eigen::Vector2d best_px = Eigen::Vector2d::Zero(), best_c = Eigen::Vector2d::Zero();
  const int r = options.search_radius_px;
  auto consider = [&](int x, int y) {
    if (x < 0 || y < 0 || x >= w || y >= h) return;
    double row = 0;
    if (!registration.color_row(x, y, row)) return;
    const double dy = row - color_px.y();
    if (dy * dy > best) return;
    Eigen::Vector2d c;
    if (!mapped(x, y, c)) return;
    const double d = (c - color_px).squaredNorm();
    if (d < best || (d == best && (y < best_px.y() || (y == best_px.y() && x < best_px.x())))) {
      best = d;
      best_px = {x, y};
      best_c = c;
    }
  };
  for (int k = 0; k <= r; ++k)
    for (int y = gy - k; y <= gy + k; ++y) {
      const int step = (y == gy - k || y == gy + k) ? 1 : std::max(1, 2 * k);
      for (int x = gx - k; x <= gx + k; x += step) consider(x, y);
    }
  if (best > 4.0 * 4.0) return std::nullopt;
  // Sub-pixel: the mapping is a shift locally (unit Jacobian).
  return best_px + (color_px - best_c);
}

// The face's depth: the nearest quarter of the valid depths in the points' bounding box (the
// face, not the background behind the jaw). `box` is scratch.
template <class Pixel>
Result<double> face_reference_depth(std::span<const Eigen::Vector2d> color_px,
                                    const Image<Pixel>& depth_mm, std::vector<float>& box) {
  if (color_px.size() != static_cast<std::size_t>(kFitLandmarkCount))
    return fail("landmarks: expected 68 points, got " + std::to_string(color_px.size()));
  if (depth_mm.empty()) return fail("landmarks: the depth map is empty");
  double x0 = 1e9, y0 = 1e9, x1 = -1e9, y1 = -1e9;
  for (const auto& p : color_px) {
    if (!p.allFinite()) return fail("landmarks: a point is not finite");
    x0 = std::min(x0, p.x());
    y0 = std::min(y0, p.y());
    x1 = std::max(x1, p.x());
    y1 = std::max(y1, p.y());
  }
  box.clear();
  for (int y = std::max(0, static_cast<int>(y0)); y <= std::min<int>(depth_mm.height - 1, y1); ++y)
    for (int x = std::max(0, static_cast<int>(x0)); x <= std::min<int>(depth_mm.width - 1, x1); ++x)
      if (depth_mm.at(x, y) > 0) box.push_back(static_cast<float>(depth_mm.at(x, y)));
  if (box.size() < 50)
    return fail("landmarks: no depth in the face box (the depth map is missing there)");
  std::nth_element(box.begin(), box.begin() + box.size() / 4, box.end());
  return static_cast<double>(box[box.size() / 4]);
}

using DepthPixels = std::array<std::optional<Eigen::Vector2d>, kFitLandmarkCount>;

// Every point's depth-image pixel, against the face's reference depth.
template <class Pixel>
Result<DepthPixels> depth_pixels_of(std::span<const Eigen::Vector2d> color_px,
                                    const Image<Pixel>& depth_mm,
                                    const KinectRegistration& registration,
                                    const LiftOptions& options, std::vector<float>& box) {
  auto reference = face_reference_depth(color_px, depth_mm, box);
  if (!reference) return reference.failure();
  DepthPixels out{};
  for (int i = 0; i < kFitLandmarkCount; ++i) {
    out[static_cast<std::size_t>(i)] = map_to_depth_pixel(
        color_px[static_cast<std::size_t>(i)], depth_mm, registration, *reference, options);
  }
  return out;
}

}  // namespace

std::optional<Eigen::Vector2d> color_to_depth_pixel(const Eigen::Vector2d& color_px,
                                                    const Image<float>& depth_mm,
                                                    const KinectRegistration& registration,
                                                    double reference_mm,
                                                    const LiftOptions& options) {
  return map_to_depth_pixel(color_px, depth_mm, registration, reference_mm, options);
}

Result<std::array<FitLandmark, kFitLandmarkCount>> lift_landmarks(
    std::span<const Eigen::Vector2d> color_px, const Image<float>& depth_mm,
    const KinectRegistration& registration, const LiftOptions& options) {
  std::vector<float> box_depths;
  return lift_landmarks(color_px, depth_mm, registration, options, box_depths);
}

Result<std::array<FitLandmark, kFitLandmarkCount>> lift_landmarks(
    std::span<const Eigen::Vector2d> color_px, const Image<float>& depth_mm,
    const KinectRegistration& registration, const LiftOptions& options, std::vector<float>& box) {
  auto pixels = depth_pixels_of(color_px, depth_mm, registration, options, box);
  if (!pixels) return pixels.failure();
  std::array<FitLandmark, kFitLandmarkCount> out{};
  for (int i = 0; i < kFitLandmarkCount; ++i) {
    FitLandmark& lm = out[static_cast<std::size_t>(i)];
    const auto& px = (*pixels)[static_cast<std::size_t>(i)];
    if (!px) continue;
    lm.valid = true;
    lm.pixel = *px;
    if (is_contour_landmark(i)) continue;
    // Strict lifting: on a rim (eyes, mouth) the point stays 2D (see lift_depth).
    lm.point =
        lift_depth(depth_mm, registration.depth_intrinsics(), *px, options.depth_radius_px, true);
  }
  return out;
}

Result<std::array<std::optional<Eigen::Vector2d>, kFitLandmarkCount>> landmark_depth_pixels(
    std::span<const Eigen::Vector2d> color_px, const DepthImage& depth_mm,
    const KinectRegistration& registration, const LiftOptions& options, std::vector<float>& box) {
  return depth_pixels_of(color_px, depth_mm, registration, options, box);
}

}  // namespace fb
