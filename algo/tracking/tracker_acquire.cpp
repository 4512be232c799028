// FaceTracker stage: finding the face, at the start and after a loss. Candidate starting poses
// (landmarks, the last good pose, the nearest surface at three yaws) tried by ICP, and the
// checks a fit must pass to count as a face.
#include <algorithm>
#include <cmath>
#include <numbers>

#include <Eigen/Geometry>

#include "algo/tracking/face_tracker_state.hpp"

namespace fb {

using namespace tracker_detail;

bool FaceTracker::State::acceptable(const IcpStats& s, bool acquiring, bool face_seen) const {
  // Acquisition is stricter on coverage (a flat wall must not pass for a face).
  const float fraction =
      acquiring ? std::max(0.5f, options.min_inlier_fraction) : options.min_inlier_fraction;
  const float rms = max_rms_mm(face_seen);
  return s.inliers >= options.min_inliers &&
         static_cast<float>(s.inliers) >= fraction * static_cast<float>(s.facing) && s.rms <= rms;
}

bool FaceTracker::State::acquire(const TrackLandmarks* landmarks, IcpStats& stats) {
  // Candidate starting poses, best evidence first: a pose from the landmarks (detection on the
  // colour image), the last good pose (a short occlusion), and a frontal face on the nearest
  // surface (depth detection) at three yaws.
  std::array<Pose, 5> candidates;
  int count = 0;
  const Box full{0, 0, width, height};
  bool from_landmarks = false;
  if (landmarks != nullptr && landmarks->points.size() >= 68) {
    // Kabsch between the model landmarks and the landmarks lifted with the depth.
    Eigen::Matrix<float, 3, 68> src, dst;
    int m = 0;
    for (int l = 17; l < 68; ++l) {
      if (!landmarks->valid.empty() && !landmarks->valid[static_cast<std::size_t>(l)]) continue;
      const Eigen::Vector2f& px = landmarks->points[static_cast<std::size_t>(l)];
      float z = 0.0f;
      if (!depth_at(smoothed, full, px.x(), px.y(), z)) continue;
      src.col(m) = landmark_current.segment<3>(3 * l);
      dst.col(m) = Eigen::Vector3f((px.x() - cx) * z / fx, (px.y() - cy) * z / fy, z);
      ++m;
    }
    if (m >= 10) {
      const Eigen::Matrix3f t = Eigen::umeyama(src.leftCols(m), dst.leftCols(m), false)
                                    .topLeftCorner<4, 4>()
                                    .eval()
                                    .block<3, 3>(0, 0);
      Pose p;
      p.r = t;
      const Eigen::Vector3f sc = src.leftCols(m).rowwise().mean();
      const Eigen::Vector3f dc = dst.leftCols(m).rowwise().mean();
      p.t = dc - p.r * sc;
      candidates[count++] = p;
      from_landmarks = true;
    }
  }
  // A detection says where the face is now; the last good pose where it was.
  if (have_last_good) candidates[count++] = last_good_pose;
  {
    // Nearest surface: a 1 cm depth histogram of every 4th pixel; the first bin with a few
    // dozen samples is the front of the nearest object (the face, for a seated subject).
    std::array<int, 256> histogram{};
    const float lo = options.min_depth_mm;
    for (int y = 0; y < height; y += 4) {
      for (int x = 0; x < width; x += 4) {
        const float d = smoothed.pixels[static_cast<std::size_t>(y) * width + x];
        if (d <= 0.0f) continue;
        const int bin = std::clamp(static_cast<int>((d - lo) / 10.0f), 0, 255);
        ++histogram[static_cast<std::size_t>(bin)];
      }
    }
    int bin = 0;
    while (bin < 256 && histogram[static_cast<std::size_t>(bin)] < 20) ++bin;
    if (bin < 256) {
      const float front = lo + 10.0f * bin;
      double su = 0, sv = 0, sz = 0;
      int m = 0;
      for (int y = 0; y < height; y += 2) {
        for (int x = 0; x < width; x += 2) {
          const float d = smoothed.pixels[static_cast<std::size_t>(y) * width + x];
          if (d <= 0.0f || d > front + options.acquire_band_mm) continue;
          su += x, sv += y, sz += d;
          ++m;
        }
      }
      if (m > 50) {
        const float z = static_cast<float>(sz / m);
        const Eigen::Vector3f centre(static_cast<float>((su / m - cx) * z / fx),
                                     static_cast<float>((sv / m - cy) * z / fy), z);
        for (float yaw_deg : {0.0f, 25.0f, -25.0f}) {
          if (count >= static_cast<int>(candidates.size())) break;
          Pose p;
          p.r = kFlip * Eigen::AngleAxisf(yaw_deg * std::numbers::pi_v<float> / 180.0f,
                                          Eigen::Vector3f::UnitY())
                            .toRotationMatrix();
          // Samples' centroid at the blob centre in x, y; the nose tip on the nearest surface.
          p.t = centre - p.r * centroid;
          const Eigen::Vector3f nose =
              centroid + Eigen::Vector3f(0.0f, 0.0f, nose_z - centroid.z());
          p.t.z() = front - (p.r * nose).z();
          candidates[count++] = p;
        }
      }
    }
  }
  // Acquisition accepts only a fit as good as tracking gives: most of the face's samples on the
  // surface (a face rotated far from the truth shows too few) with a residual near the sensor
  // noise (ICP can converge to a wrong rotation at the right place with a few mm RMS). Before
  // calibration the mean face fits a real one only to a few mm, so the RMS bound is then
  // acceptable()'s alone (the tracking one, or uncalibrated_max_rms_mm when landmarks confirm a
  // face).
  auto good = [&](const IcpStats& s) {
    return acceptable(s, true, from_landmarks) &&
           static_cast<float>(s.inliers) >= options.acquire_min_sample_fraction * n &&
           (!calibrated || s.rms <= options.acquire_max_rms_mm);
  };
  // With landmarks, a candidate must also put the model's landmarks on them: median
  // reprojection error over the interior points.
  auto landmark_error_px = [&](const Pose& p) {
    std::array<float, 68> errors{};
    int m = 0;
    for (int l = 17; l < 68; ++l) {
      if (!landmarks->valid.empty() && !landmarks->valid[static_cast<std::size_t>(l)]) continue;
      const Eigen::Vector3f x = landmark_in_camera(p, l);
      if (x.z() <= 1.0f) continue;
      errors[static_cast<std::size_t>(m++)] =
          (pixel_of(x) - landmarks->points[static_cast<std::size_t>(l)]).norm();
    }
    if (m < 10) return 1e9f;
    std::nth_element(errors.begin(), errors.begin() + m / 2, errors.begin() + m);
    return errors[static_cast<std::size_t>(m / 2)];
  };
  bool found = false;
  IcpStats best;
  Pose best_pose;
  for (int c = 0; c < count; ++c) {
    Pose p = candidates[c];
    IcpStats s = icp(smoothed, full, p, options.acquire_iterations, 40.0f, options.icp_gate_mm);
    if (!acceptable(s, true, from_landmarks)) continue;
    if (calibrated) {
      // The face may show any expression: fit the weights at this pose and refine it before
      // judging the residual (a neutral face on an open jaw leaves several mm).
      int unused = 0;
      solve_weights(smoothed, full, p, options.weight_iterations, true, landmarks, unused);
      s = icp(smoothed, full, p, options.icp_iterations, options.icp_gate_mm, options.icp_gate_mm);
    }
    if (!good(s) || (from_landmarks && landmark_error_px(p) > options.acquire_landmark_px)) {
      weights = previous_weights;
      update_current();
      continue;
    }
    found = true;
    best = s;
    best_pose = p;
    break;  // candidates are in order of evidence: the first good fit is the face
  }
  stats = best;
  if (found) pose = best_pose;
  return found;
}

}  // namespace fb
