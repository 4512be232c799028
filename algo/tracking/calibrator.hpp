// Calibration (an engine with its frames): the first calibration_frames usable frames of a
// neutral face fit the subject's identity coefficients with the face model's identity PCA
// (Tikhonov prior) jointly with those frames' poses, then measure where this face's depth
// samples and landmarks sit against the fitted face (the offsets). FaceWarehouse 4.3.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "algo/core/image.hpp"
#include "algo/core/rigid_pose.hpp"
#include "algo/tracking/rigid_icp.hpp"
#include "algo/tracking/subject_rig.hpp"
#include "algo/tracking/tracker_geometry.hpp"
#include "algo/tracking/tracker_options.hpp"

namespace fb {

class Calibrator {
 public:
  // Allocates the frames. `landmark_huber_px` and `landmark_noise_px` are the weight solve's
  // (WeightSolverOptions): the calibration reprojects the landmarks the same way.
  void allocate(const CalibratorOptions& options, const TrackerCamera& camera,
                float landmark_huber_px, float landmark_noise_px, int n);
  void clear() { count_ = 0; }
  int count() const { return count_; }
  int frames_left() const { return options_.calibration_frames - count_; }
  bool complete() const { return count_ >= options_.calibration_frames; }
  // Stores a tracked frame of the neutral face: its smoothed depth in `box`, the pose, and the
  // landmarks (null: none).
  void add_frame(const Image<float>& smoothed, const PixelRect& box, const RigidPoseF& pose,
                 const TrackLandmarks* landmarks);
  // Fits the identity to the stored frames and builds the subject's rig with it (weights left
  // at 0); returns the mean RMS of the stored frames re-tracked with the fitted face.
  float calibrate(SubjectRig& rig, const RigidIcp& icp, ShapeVector& weights);
  // The pose of the last stored frame after calibrate().
  const RigidPoseF& last_pose() const { return pose_[static_cast<std::size_t>(count_ - 1)]; }

 private:
  struct NormalEquations;
  void fit_identity(SubjectRig& rig, ShapeVector& weights, Eigen::VectorXd& c);
  void add_frame_rows(const SubjectRig& rig, int f, NormalEquations& e) const;
  void landmark_offsets(SubjectRig& rig, ShapeVector& weights) const;
  void depth_offsets(SubjectRig& rig, ShapeVector& weights);

  CalibratorOptions options_;
  TrackerCamera camera_;
  float landmark_huber_px_ = 4.0f;
  float landmark_noise_px_ = 1.5f;
  float gate_mm_ = 10.0f;  // Tukey cut-off of the depth rows (RigidIcpOptions::icp_gate_mm)
  std::vector<Image<float>> depth_;
  std::vector<PixelRect> box_;
  std::vector<RigidPoseF> pose_;
  std::vector<Eigen::Vector2f> landmarks_;    // calibration_frames x 68
  std::vector<std::uint8_t> landmark_valid_;  // calibration_frames x 68
  std::vector<float> landmark_scale_;         // per frame: landmark_scale()
  int count_ = 0;
  std::vector<float> offset_sum_;  // n: depth_offsets()' sums of residuals
  std::vector<int> offset_seen_;   // n: and frames seen
};

}  // namespace fb
