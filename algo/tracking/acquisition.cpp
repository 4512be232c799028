#include "algo/tracking/acquisition.hpp"

#include <algorithm>
#include <numbers>

#include <Eigen/Geometry>

namespace fb {
namespace {

const Eigen::Matrix3f kFlip = Eigen::Vector3f(1.0f, -1.0f, -1.0f).asDiagonal();

// Kabsch between the model landmarks and the landmarks lifted with the depth.
bool landmark_pose(const SubjectRig& rig, const TrackerCamera& camera, const Image<float>& smoothed,
                   const TrackLandmarks& landmarks, RigidPoseF& p) {
  Eigen::Matrix<float, 3, 68> src, dst;
  int m = 0;
  for (int l = 17; l < 68; ++l) {
    if (!landmarks.valid.empty() && !landmarks.valid[static_cast<std::size_t>(l)]) continue;
    const Eigen::Vector2f& px = landmarks.points[static_cast<std::size_t>(l)];
    float z = 0.0f;
    if (!camera.depth_at(smoothed, camera.full(), px.x(), px.y(), z)) continue;
    src.col(m) = rig.landmark_current.segment<3>(3 * l);
    dst.col(m) = camera.ray_point(px, z);
    ++m;
  }
  if (m < 10) return false;
  const Eigen::Matrix3f t = Eigen::umeyama(src.leftCols(m), dst.leftCols(m), false)
                                .topLeftCorner<4, 4>()
                                .eval()
                                .block<3, 3>(0, 0);
  p.r = t;
  const Eigen::Vector3f sc = src.leftCols(m).rowwise().mean();
  const Eigen::Vector3f dc = dst.leftCols(m).rowwise().mean();
  p.t = dc - p.r * sc;
  return true;
}

// Nearest surface: a 1 cm depth histogram of every 4th pixel; the first bin with a few dozen
// samples is the front of the nearest object (the face, for a seated subject). The face is
// placed frontal (and at +-25 deg yaw) with its samples' centroid at the blob's centre and the
// nose tip on that surface.
void nearest_surface_poses(const SubjectRig& rig, const TrackerCamera& camera,
                           const Image<float>& smoothed, float lo, float band_mm, StartPoses& out) {
  const int width = camera.width, height = camera.height;
  std::array<int, 256> histogram{};
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
  if (bin >= 256) return;
  const float front = lo + 10.0f * bin;
  double su = 0, sv = 0, sz = 0;
  int m = 0;
  for (int y = 0; y < height; y += 2) {
    for (int x = 0; x < width; x += 2) {
      const float d = smoothed.pixels[static_cast<std::size_t>(y) * width + x];
      if (d <= 0.0f || d > front + band_mm) continue;
      su += x, sv += y, sz += d;
      ++m;
    }
  }
  if (m <= 50) return;
  const float z = static_cast<float>(sz / m);
  const Eigen::Vector3f centre(static_cast<float>((su / m - camera.cx) * z / camera.fx),
                               static_cast<float>((sv / m - camera.cy) * z / camera.fy), z);
  for (float yaw_deg : {0.0f, 25.0f, -25.0f}) {
    if (out.count >= static_cast<int>(out.poses.size())) break;
    RigidPoseF p;
    p.r = kFlip *
          Eigen::AngleAxisf(yaw_deg * std::numbers::pi_v<float> / 180.0f, Eigen::Vector3f::UnitY())
              .toRotationMatrix();
    p.t = centre - p.r * rig.centroid;
    const Eigen::Vector3f nose =
        rig.centroid + Eigen::Vector3f(0.0f, 0.0f, rig.nose_z - rig.centroid.z());
    p.t.z() = front - (p.r * nose).z();
    out.poses[static_cast<std::size_t>(out.count++)] = p;
  }
}

}  // namespace

StartPoses start_poses(const SubjectRig& rig, const TrackerCamera& camera,
                       const Image<float>& smoothed, const TrackLandmarks* landmarks,
                       const RigidPoseF* last_good, float min_depth_mm,
                       const AcquireOptions& options) {
  StartPoses out;
  RigidPoseF p;
  if (landmarks != nullptr && landmarks->points.size() >= 68 &&
      landmark_pose(rig, camera, smoothed, *landmarks, p)) {
    out.poses[static_cast<std::size_t>(out.count++)] = p;
    out.from_landmarks = true;
  }
  // A detection says where the face is now; the last good pose where it was.
  if (last_good != nullptr) out.poses[static_cast<std::size_t>(out.count++)] = *last_good;
  nearest_surface_poses(rig, camera, smoothed, min_depth_mm, options.acquire_band_mm, out);
  return out;
}

float landmark_error_px(const SubjectRig& rig, const TrackerCamera& camera, const RigidPoseF& p,
                        const TrackLandmarks& landmarks) {
  std::array<float, 68> errors{};
  int m = 0;
  for (int l = 17; l < 68; ++l) {
    if (!landmarks.valid.empty() && !landmarks.valid[static_cast<std::size_t>(l)]) continue;
    const Eigen::Vector3f x = rig.landmark_in_camera(p, l);
    if (x.z() <= 1.0f) continue;
    errors[static_cast<std::size_t>(m++)] =
        (camera.pixel_of(x) - landmarks.points[static_cast<std::size_t>(l)]).norm();
  }
  if (m < 10) return 1e9f;
  std::nth_element(errors.begin(), errors.begin() + m / 2, errors.begin() + m);
  return errors[static_cast<std::size_t>(m / 2)];
}

}  // namespace fb
