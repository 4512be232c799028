#include "algo/tracking/detected_landmarks.hpp"

#include <chrono>

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
  const auto start = std::chrono::steady_clock::now();
  LandmarkFrameResult result;
  have_ = false;
  auto finish = [&](const char* reason) {
    result.reason = reason;
    result.ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    return result;
  };
  if (color.empty()) return finish("no colour image");
  auto detected = detector_.detect(color);
  if (!detected) return finish("no face found in the colour image");
  result.tracked_window = detected->tracked;
  depth_float_.resize(depth.width, depth.height);
  for (std::size_t i = 0; i < depth.pixels.size(); ++i) depth_float_.pixels[i] = depth.pixels[i];
  auto lifted = lift_landmarks(detected->points, depth_float_, registration_, {}, box_depths_);
  if (!lifted) return finish("no depth under the detected face");
  for (int l = 0; l < 68; ++l) {
    const FitLandmark& lm = (*lifted)[static_cast<std::size_t>(l)];
    valid_[static_cast<std::size_t>(l)] = lm.valid ? 1 : 0;
    points_[static_cast<std::size_t>(l)] = lm.pixel.cast<float>();
    if (lm.valid && l >= 17) ++result.valid_points;
  }
  if (result.valid_points < 20) return finish("too few landmarks map into the depth image");
  have_ = true;
  result.found = true;
  return finish("");
}

}  // namespace fb
