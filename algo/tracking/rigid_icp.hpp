// Rigid projective point-to-plane ICP of the subject's current face (the rig's samples) against
// smoothed depth (an engine: it keeps no state between calls). Each iteration linearises
//   r_i = n_i . (x_i - q_i),  x <- Rw (x - pivot) + pivot + dt,  J_i = [(x_i - pivot) x n_i; n_i]
// about the face's centroid, with Tukey weights whose cut-off shrinks from the first gate.
// The loss test of a fit lives here too: it reads only the fit's statistics.
#pragma once

#include "algo/core/image.hpp"
#include "algo/core/rigid_pose.hpp"
#include "algo/tracking/occlusion_mask.hpp"
#include "algo/tracking/subject_rig.hpp"
#include "algo/tracking/tracker_geometry.hpp"
#include "algo/tracking/tracker_options.hpp"

namespace fb {

struct IcpStats {
  int facing = 0;
  int hidden = 0;  // facing samples inside the image the occlusion mask hides
  int used = 0;
  int inliers = 0;
  float rms = 0.0f;
};

class RigidIcp {
 public:
  RigidIcp() = default;
  explicit RigidIcp(const RigidIcpOptions& options) : options_(options) {}
  // `iterations` at most; the Tukey gate halves from first_gate down to gate. The statistics
  // are of the last iteration's association.
  IcpStats run(const SubjectRig& rig, const TrackerCamera& camera, const OcclusionMask& mask,
               const Image<float>& image, const PixelRect& b, RigidPoseF& p, int iterations,
               float first_gate, float gate) const;
  const RigidIcpOptions& options() const { return options_; }

 private:
  RigidIcpOptions options_;
};

// The RMS bound of a fit: before calibration the model is the mean face, which fits an
// atypical one only to a few mm, so the bound is looser there when landmarks confirm a face.
inline float max_fit_rms_mm(const LossOptions& o, bool calibrated, bool face_seen) {
  return calibrated || !face_seen ? o.max_rms_mm : o.uncalibrated_max_rms_mm;
}

// Whether a fit is the face; acquisition is stricter on coverage (a flat wall must not pass).
inline bool fit_acceptable(const IcpStats& s, const LossOptions& o, bool acquiring, float rms) {
  const float fraction = acquiring ? std::max(0.5f, o.min_inlier_fraction) : o.min_inlier_fraction;
  return s.inliers >= o.min_inliers &&
         static_cast<float>(s.inliers) >= fraction * static_cast<float>(s.facing) && s.rms <= rms;
}

}  // namespace fb
