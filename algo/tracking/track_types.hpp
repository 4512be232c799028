// What the tracker is given besides depth: 2D landmarks, a stored subject rig, a source of the
// subject's own blendshapes. Pure data and interfaces (algo/ does not depend on storage/).
#pragma once

#include <cstdint>
#include <span>
#include <string_view>
#include <utility>
#include <vector>

#include <Eigen/Core>

namespace fb {

// The gaze shapes (eyeLook*): they turn the eyeballs, which depth does not see (see
// WeightSolverOptions::hold_gaze_shapes).
inline bool is_gaze_shape(std::string_view name) {
  return name.starts_with("eyeLook");
}

// Optional 2D landmarks: the 68 iBUG points in DEPTH image pixels (detect on colour, map
// through the registration); `valid[i] == 0` drops point i. Contour points 0-16 are ignored
// (they slide along the silhouette).
struct TrackLandmarks {
  std::span<const Eigen::Vector2f> points;
  std::span<const std::uint8_t> valid;  // empty = all valid
  // The source's typical error, px rms per image axis (0 = landmark_noise_px): the landmark
  // rows count (landmark_noise_px / noise_px)^2 as much.
  float noise_px = 0.0f;
};

// How much a source's landmark rows count against the ones the weights are set for.
inline float landmark_scale(const TrackLandmarks& l, float landmark_noise_px) {
  if (l.noise_px <= 0.0f) return 1.0f;
  const float ratio = landmark_noise_px / l.noise_px;
  return ratio * ratio;
}

// A subject's personal blendshape rig in the face model's topology (storage's RigData seen
// through spans).
struct TrackerRig {
  std::span<const float> neutral;  // 3 * model.vertex_count, model frame, mm
  // (model fitting-shape index, full shape positions of 3 * vertex_count floats)
  std::vector<std::pair<int, std::span<const float>>> shapes;
};

// Blendshapes that depend on who is tracked. In a bilinear model (FaceWarehouse eq. 10,
// V = C x_2 w_id x_3 w_exp) every subject has their own expression deltas, so once calibration
// has fitted the identity the tracker asks this source for the subject's deltas instead of
// keeping the model's fixed ones.
class SubjectBlendshapes {
 public:
  virtual ~SubjectBlendshapes() = default;
  // `identity`: the calibrated coefficients of the tracker's FaceModel (sigma units).
  // `deltas`: column-major, 3 * vertices.size() rows (xyz per vertex, model frame, mm) by the
  // model's fitting shapes; on entry it holds the model's deltas, and the source overwrites
  // the columns of the shapes it knows.
  virtual void subject_deltas(std::span<const float> identity,
                              std::span<const std::uint32_t> vertices,
                              std::span<float> deltas) const = 0;
};

}  // namespace fb
