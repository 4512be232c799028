// The fusion face box from a detected face (issue 35, capture): dlib's 68 points on the colour
// image, moved into the depth image through the camera's registration (lift_landmarks), grown
// by the face model's own proportions so the box holds the whole forehead and chin, and the
// face's depth, so fusion starts on the face and not on the nearest surface.
#pragma once

#include <array>
#include <span>

#include <Eigen/Core>

#include "algo/core/image.hpp"
#include "algo/core/result.hpp"
#include "algo/facemodel/face_model.hpp"
#include "algo/fitting/face_fit.hpp"
#include "algo/fusion/fusion_types.hpp"
#include "algo/landmarks/landmark_detector.hpp"
#include "algo/sensor/kinect_calibration.hpp"

namespace fb {

// How far the face (the top of the forehead, the front of the chin, cheek to cheek) reaches
// beyond the bounding box of the 68 landmarks, as fractions of that box's height (above the
// brows, below the chin point) and width (each side). The defaults are face_proportions() of
// the project's face model (data/facemodel.fbfm), for callers that do not load it.
struct FaceProportions {
  double above = 0.363;
  double below = 0.038;
  double sides = 0.0;  // the jaw contour points are already the face's widest
};

// Measured on the model's mean face (its face region, vertices 0..face_vertex_count-1,
// against its landmark vertices, frontal).
FaceProportions face_proportions(const FaceModel& model);

struct FaceRegionOptions {
  // Added beyond the face, as fractions of its grown size: dlib's box error and the face
  // turning inside its box between two frames; on the sides the sides of the head and below
  // the underside of the jaw, which hold the tracker's rotation (yaw, pitch) as the head
  // turns (a box of the face alone gave twice the rotation error on the plain head turns).
  // Nearer or farther surfaces there (chest, desk, hands) are gated out by the face's depth.
  double side_margin = 0.35;
  double top_margin = 0.10;
  double bottom_margin = 0.30;
};

// The box from landmarks in the depth image (lift_landmarks' output); its face_depth_mm is the
// median depth of the lifted points. Fails with fewer than 20 valid points.
Result<FaceBox> face_box_from_landmarks(std::span<const FitLandmark> landmarks,
                                        const FaceProportions& proportions, int width, int height,
                                        const FaceRegionOptions& options = {});

// The cut below the chin (FaceBox::chin_mm, down) from the lifted landmarks: the face's axis
// from the nose bridge (27) to the chin (8), each back-projected at the depth of the lifted
// points near it (nose bridge; lips, since the chin is a contour point and not lifted), or the
// face's depth when those stayed 2D. Needs the box's face_depth_mm; else no cut.
void set_chin_cut(std::span<const FitLandmark> landmarks, const PinholeIntrinsics& depth_intrinsics,
                  FaceBox& box);

struct DetectedFaceRegion {
  FaceBox box;                                     // depth image
  std::array<Eigen::Vector2d, 68> color_points{};  // dlib's, colour image px
};

// dlib on `color`, lifted into `depth` through `registration`, grown into the face box. The
// detector searches the whole image (its tracking is reset first).
Result<DetectedFaceRegion> detect_face_region(LandmarkDetector& detector, const ColorImage& color,
                                              const DepthImage& depth,
                                              const KinectRegistration& registration,
                                              const FaceProportions& proportions,
                                              const FaceRegionOptions& options = {});

}  // namespace fb
