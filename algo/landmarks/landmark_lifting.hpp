// From colour-image landmarks to fitting landmarks (FaceWarehouse 3.2): each point is moved
// into the depth image through the inverse of the depth-to-colour registration; interior points
// (iBUG 17-67) are lifted to 3D with the depth there, contour points (0-16) stay 2D.
#pragma once

#include <array>
#include <optional>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "algo/core/camera_model.hpp"
#include "algo/core/image.hpp"
#include "algo/core/result.hpp"
#include "algo/fitting/face_fit.hpp"
#include "algo/sensor/kinect_calibration.hpp"

namespace fb {

struct LiftOptions {
  int search_radius_px = 5;      // around the registration's first guess
  double depth_band_mm = 100.0;  // depths this far from the face's median are background
  int depth_radius_px = 2;       // see lift_depth()
};

// Depth-image pixel whose registered colour position is `color_px`, assuming the surface there
// is near `reference_mm` where the depth has no sample (contour points on the silhouette).
std::optional<Eigen::Vector2d> color_to_depth_pixel(const Eigen::Vector2d& color_px,
                                                    const Image<float>& depth_mm,
                                                    const KinectRegistration& registration,
                                                    double reference_mm,
                                                    const LiftOptions& options = {});

// All 68 points. Fails when the face region has no depth at all ("no depth in the face box").
// Interior points without depth become 2D-only; points outside the image are invalid.
Result<std::array<FitLandmark, kFitLandmarkCount>> lift_landmarks(
    std::span<const Eigen::Vector2d> color_px, const Image<float>& depth_mm,
    const KinectRegistration& registration, const LiftOptions& options = {});
// The same with a caller's scratch buffer for the face box's depths, so a caller running every
// frame (the tracker's landmark source) reuses it instead of allocating it per frame.
Result<std::array<FitLandmark, kFitLandmarkCount>> lift_landmarks(
    std::span<const Eigen::Vector2d> color_px, const Image<float>& depth_mm,
    const KinectRegistration& registration, const LiftOptions& options,
    std::vector<float>& box_depths);

// Only the depth-image pixels of the 68 points, straight from the raw 16-bit frame (no 3D
// points): what the tracker's landmark rows use, without converting the frame to float. The
// same pixels as lift_landmarks(); a point without one is nullopt.
Result<std::array<std::optional<Eigen::Vector2d>, kFitLandmarkCount>> landmark_depth_pixels(
    std::span<const Eigen::Vector2d> color_px, const DepthImage& depth_mm,
    const KinectRegistration& registration, const LiftOptions& options,
    std::vector<float>& box_depths);

// Depth as float mm (for raw sensor frames).
Image<float> depth_to_float(const DepthImage& depth_mm);

}  // namespace fb
