// Real-time head pose + blendshape tracking on depth frames (FaceWarehouse 4.3, wrinkle paper
// 4.1): rigid projective point-to-plane ICP of the subject's current face against the
// temporally smoothed depth, then blendshape weights in [0, 1] by bounded least squares on the
// same depth samples plus optional 2D landmarks, with temporal smoothness. A visibility mask
// (samples with depth far in front of them are hidden) and robust weights keep an occluder (a
// hand) from dragging pose or weights; a lost face is reported and re-acquired.
//
// The tracker is a facade over rooms (InfiniTAM's objects and engines, as algo/fusion): the
// SubjectRig (the subject's blendshapes at a vertex subsample), the DepthSmoother, the
// OcclusionMask, RigidIcp, the WeightSolver, the Calibrator (identity from the first
// calibration_frames usable frames, or set_identity() / set_rig()) and the acquisition's start
// poses. Options are grouped per room (tracker_options.hpp).
//
// Per-frame cost: ring buffer + temporal smoothing in the face box, ICP on N samples, K x K
// normal equations (N x K GEMM) and projected Gauss-Seidel. Steady-state track() does not
// allocate; every buffer is sized in create() / calibration.
//
// Units mm; camera frame x right, y down, z forward (depth camera); model frame +X subject's
// left, +Y up, +Z out of the face. Pure: no files, no sockets, no threads.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <string_view>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "algo/core/camera_model.hpp"
#include "algo/core/image.hpp"
#include "algo/core/result.hpp"
#include "algo/facemodel/face_model.hpp"
#include "algo/tracking/bounded_lsq.hpp"
#include "algo/tracking/pose_filter.hpp"
#include "algo/tracking/track_types.hpp"
#include "algo/tracking/tracker_options.hpp"

namespace fb {

enum class TrackState : std::uint8_t {
  kSearching,    // no face yet (or still lost): outputs hold the last good values
  kCalibrating,  // tracking with the provisional identity while collecting calibration frames
  kTracking,
  kRecovered,  // tracking again after loss on this frame
  kLost,       // the face was lost on this frame (report + keep the last good values)
  kBadInput,   // wrong size or no valid depth at all
};
const char* to_string(TrackState state);

struct TrackTimes {
  double smooth_ms = 0.0;     // ring buffer + temporal smoothing in the face box
  double icp_ms = 0.0;        // rigid ICP
  double weights_ms = 0.0;    // blendshape solve (incl. landmark rows when given)
  double acquire_ms = 0.0;    // re-acquisition (only on search frames)
  double calibrate_ms = 0.0;  // identity fit (only on the frame that finishes calibration)
  double total_ms() const { return smooth_ms + icp_ms + weights_ms + acquire_ms + calibrate_ms; }
};

struct TrackReport {
  TrackState state = TrackState::kSearching;
  bool face_found = false;       // pose and weights are from this frame
  const char* loss_reason = "";  // why the face was lost / input rejected
  RigidPose camera_from_model;   // filtered (what is streamed)
  RigidPose raw_camera_from_model;
  int shape_count = 0;
  std::array<float, kMaxTrackedShapes> weights{};  // model fitting-shape order, [0, 1]
  // With WeightSolverOptions::report_weight_sigma: each weight's standard error from this frame's
  // data alone (no priors; given the pose), +inf for a shape the data does not see; else 0.
  std::array<float, kMaxTrackedShapes> weight_sigma{};
  int samples_used = 0;  // samples with a depth correspondence
  int inliers = 0;       // of those, within the Tukey cut-off
  float rms_mm = 0.0f;   // point-to-plane RMS of the inliers
  int landmarks_used = 0;
  int calibration_frames_left = 0;
  // Occlusion as data: the share of the face's samples (facing the camera, inside the image)
  // the occlusion mask hides on this frame, and whether it is at least
  // OcclusionMaskOptions::occlusion_report_fraction. Frames that measure nothing (searching after a
  // loss) hold the last values; the weights of the shapes under the occluder are held too
  // (WeightSolverOptions::hidden_hold).
  float occluded_fraction = 0.0f;
  bool occluded = false;
  TrackTimes times;  // wall clock of the calling thread's work
};

class FaceTracker {
 public:
  // `model` must outlive the tracker (it is read, never copied: 20 MB). Allocates every buffer.
  static Result<std::unique_ptr<FaceTracker>> create(const FaceModel& model,
                                                     const PinholeIntrinsics& intrinsics,
                                                     const TrackerOptions& options = {});
  ~FaceTracker();
  FaceTracker(const FaceTracker&) = delete;
  FaceTracker& operator=(const FaceTracker&) = delete;

  // Uses a known identity (sigma units) and skips calibration.
  Result<void> set_identity(std::span<const float> coefficients);
  // Uses a stored subject rig (the face model's topology) and skips calibration: its neutral
  // replaces the identity face, its shapes replace the model's expression deltas (shape - neutral)
  // for the fitting shapes they name; fitting shapes the rig lacks keep the model's delta.
  // identity() is all zeros afterwards (a rig has no identity coefficients).
  Result<void> set_rig(const TrackerRig& rig);
  // Builds the subject's own blendshapes from `source` whenever an identity is set (by
  // calibration or set_identity()); nullptr goes back to the model's. Not owned: it must
  // outlive the tracker. A stored rig (set_rig) takes precedence.
  void set_subject_blendshapes(const SubjectBlendshapes* source);
  // Forgets the subject and the pose: the next frames search and calibrate again.
  void reset();

  // Tracks one depth frame (depth camera, mm, 0 = invalid) taken at `time_s`; landmarks may be
  // null. Never fails: bad input and loss are states of the report.
  void track(const DepthImage& depth, double time_s, const TrackLandmarks* landmarks,
             TrackReport& report);

  bool calibrated() const;
  std::span<const float> identity() const;  // identity_modes coefficients
  int sample_count() const;
  int shape_count() const;  // the model's fitting shapes (53)
  // Shapes with little depth signal (held near 0 by a strong prior), model indices.
  std::span<const int> weak_shapes() const;
  std::span<const std::string> shape_names() const;

  struct State;

 private:
  explicit FaceTracker(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;
};

}  // namespace fb
