#include "algo/tracking/detected_landmarks.hpp"

#include <chrono>

#include "algo/core/clock.hpp"
#include "algo/landmarks/landmark_lifting.hpp"

namespace fb {

TrackLandmarkSource::TrackLandmarkSource(LandmarkDetector detector,
                                         const KinectCalibration& calibration)
    : detector_(std::move(detector)), registration_(calibration) {
  view_.points = points_;
  view_.valid = valid_;
  view_.noise_px = kDlibLandmarkNoisePx;
}

LandmarkFrameResult TrackLandmarkSource::detect(const ColorImage& color, const DepthImage& depth) {
  const auto start = Clock::now();
  LandmarkFrameResult result;
  have_ = false;
  auto finish = [&](const char* reason) {
    result.reason = reason;
    result.ms = ms_since(start);
    return result;
  };
  if (color.empty()) return finish("no colour image");
  auto detected = detector_.detect(color);
  if (!detected) return finish("no face found in the colour image");
  result.tracked_window = detected->tracked;
  auto mapped = landmark_depth_pixels(detected->points, depth, registration_, {}, box_depths_);
  if (!mapped) return finish("no depth under the detected face");
  for (int l = 0; l < 68; ++l) {
    const auto& px = (*mapped)[static_cast<std::size_t>(l)];
    valid_[static_cast<std::size_t>(l)] = px ? 1 : 0;
    points_[static_cast<std::size_t>(l)] =
        px ? Eigen::Vector2f(px->cast<float>()) : Eigen::Vector2f::Zero();
    if (px && l >= 17) ++result.valid_points;
  }
  if (result.valid_points < 20) return finish("too few landmarks map into the depth image");
  have_ = true;
  result.found = true;
  return finish("");
}

}  // namespace fb
