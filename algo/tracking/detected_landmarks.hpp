// The tracker's 2D landmarks from dlib on the colour image (algo/landmarks): the 68 iBUG points
// found by the HOG detector + shape predictor, moved into the depth image through the inverse
// depth-to-colour registration (landmark_depth_pixels). Two uses:
//  - every frame (`facebooth track --landmarks dlib`): landmark rows in the weight solve;
//  - re-acquisition: while the tracker searches (start, after loss) the detection gives the
//    tracker a face pose to start ICP from (FaceTracker's landmark candidate), so the face is
//    found again by detection rather than by waiting for the depth heuristics.
// Separate from fb_tracking so the tracker itself stays free of dlib.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include <Eigen/Core>

#include "algo/core/image.hpp"
#include "algo/core/result.hpp"
#include "algo/landmarks/landmark_detector.hpp"
#include "algo/sensor/kinect_calibration.hpp"
#include "algo/tracking/face_tracker.hpp"

namespace fb {

// dlib's error per image axis, px rms over the interior points: `facebooth-lab eval track --landmarks
// dlib` measures 2.52 on the synthetic colour render (dlib_landmark_error_px, 5 seeds). The
// tracker weighs its points by it (TrackLandmarks::noise_px) against the 1.5 px its landmark
// weights are set for.
constexpr float kDlibLandmarkNoisePx = 2.5f;

struct LandmarkFrameResult {
  bool found = false;
  const char* reason = "";      // why not (no colour image, no face, no depth there)
  int valid_points = 0;         // interior points (17-67) mapped into the depth image
  double ms = 0.0;              // wall time of detection + shape prediction + mapping
  bool tracked_window = false;  // the detector searched only around the last face
};

class TrackLandmarkSource {
 public:
  TrackLandmarkSource(LandmarkDetector detector, const KinectCalibration& calibration);

  // Detects on `color` and maps into `depth`'s pixels. On success `landmarks()` points at the
  // result until the next call; on failure it is null.
  LandmarkFrameResult detect(const ColorImage& color, const DepthImage& depth);
  const TrackLandmarks* landmarks() const { return have_ ? &view_ : nullptr; }
  // The next detection searches the whole image (after the tracker lost the face).
  void reset() { detector_.reset_tracking(); }
  // A camera with another registration (rebuilds the tables: not for the frame loop).
  void set_calibration(const KinectCalibration& calibration) {
    registration_ = KinectRegistration(calibration);
  }

 private:
  LandmarkDetector detector_;
  KinectRegistration registration_;
  std::vector<float> box_depths_;  // landmark_depth_pixels' scratch
  std::array<Eigen::Vector2f, 68> points_{};
  std::array<std::uint8_t, 68> valid_{};
  TrackLandmarks view_;
  bool have_ = false;
};

}  // namespace fb
