// Where the atlas should read each surface point's colour, corrected by the take's own feature
// points. The fitted mesh is right in depth but slides tangentially (a brow, an eyelid or a lip
// fitted 1-2 mm off), and the atlas, keyed by the mesh's UVs, inherits the slide: the painted
// brow lands on the UVs of the skin above it. A landmark detector's points on several frames of
// the take say where each landmark's vertex (the detector's embedding on the face model) really
// is in each image. Per landmark, the tangential offset that brings the vertex's projection onto
// the detected points is solved over all the frames that face it (robust least squares, which
// averages the detector's frame-to-frame error), and the offsets are spread smoothly over the
// mesh by a kernel smoother that fades to zero away from the landmarks. The atlas then samples
// each texel at its surface point plus that offset: a smooth warp of the atlas in UV space.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "algo/core/camera_model.hpp"
#include "algo/core/result.hpp"
#include "algo/sensor/kinect_calibration.hpp"

namespace fb {

using FeaturePoints = std::array<Eigen::Vector2d, 68>;  // iBUG 68 order, colour image px

// One frame's detected points and where the mesh is in that frame.
struct FeatureView {
  RigidPose camera_from_model;  // depth camera frame
  FeaturePoints points;
};

struct FeatureWarpOptions {
  int first_landmark = 17;  // the contour (0-16) follows the silhouette, not a surface point
  float min_facing = 0.5f;  // a landmark is used in views where its normal faces this much
  double noise_px = 3.0;    // the detector's error per frame (robust scale: Huber at this)
  double prior_mm = 1.5;    // the fit's tangential error: shrinks a landmark seen in few views
  double max_offset_mm = 4.0;
  double kernel_mm = 6.0;  // the smoother's Gaussian width on the mesh (model frame)
  double fade = 0.2;       // kernel mass below which the offset fades to zero (no landmark near)
  int min_views = 2;       // views a landmark needs to be corrected
};

struct FeatureWarp {
  std::vector<float> offsets;  // 3 per vertex, model frame, mm: add to read the right colour
  int landmarks = 0;           // landmarks corrected
  int views = 0;
  double residual_px_before = 0.0;  // median |detected - projected| over landmarks and views
  double residual_px_after = 0.0;   // ... with the landmark's offset applied
  double mean_offset_mm = 0.0;      // over the corrected landmarks
};

// `landmark_vertices`: the mesh vertex each of the 68 points marks. Fails when the vertices are
// out of range; a warp with no corrected landmark (offsets all zero) is a valid answer.
Result<FeatureWarp> estimate_feature_warp(std::span<const float> vertices,
                                          std::span<const float> normals,
                                          std::span<const std::uint32_t> landmark_vertices,
                                          std::span<const FeatureView> views,
                                          const KinectRegistration& registration,
                                          const FeatureWarpOptions& options = {});

}  // namespace fb
