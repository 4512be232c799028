// Real-time head pose + blendshape tracking on depth frames (FaceWarehouse 4.3, wrinkle paper
// 4.1): rigid projective point-to-plane ICP of the subject's current face against the
// temporally smoothed depth, then blendshape weights in [0, 1] by bounded least squares on the
// same depth samples plus optional 2D landmarks, with temporal smoothness. A visibility mask
// (samples with depth far in front of them are hidden) and robust weights keep an occluder (a
// hand) from dragging pose or weights; a lost face is reported and re-acquired.
//
// Subject: the first `calibration_frames` usable frames fit identity coefficients with the
// face model's identity PCA (Tikhonov prior, alternating with pose and expression), or
// set_identity() loads a known identity. The subject's blendshapes (identity face + the
// model's expression deltas) are then precomputed once at a fixed vertex subsample
// ("rig"), so a frame only streams a 3N x K matrix and solves a K x K system.
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

namespace fb {

struct TrackerOptions {
  // --- Depth preprocessing ---
  // Temporal smoothing: weighted mean of the last k depth frames per pixel (wrinkle paper:
  // k = 5). Older frames only count where they agree with the newest one within
  // temporal_range_mm (tri-weight), so motion does not smear.
  int temporal_frames = 5;
  float temporal_range_mm = 4.0f;
  float temporal_decay = 0.7f;  // weight of frame age a: decay^a
  // Spatial smoothing after the temporal mean (KinectFusion filters raw depth the same way):
  // mean over the (2r+1)^2 neighbours that are valid and within spatial_range_mm of the centre
  // pixel, so depth edges (eye and mouth openings, the silhouette) do not blur. 0 = off.
  // eval track, 5 seeds: depth-only weight MAE 0.0163 -> 0.0134, occluder worst frame 0.204 ->
  // 0.151; 20 seeds 0.0082 -> 0.0077. About 0.1 ms a frame.
  int spatial_radius_px = 1;
  float spatial_range_mm = 3.0f;
  float min_depth_mm = 400.0f;
  float max_depth_mm = 2000.0f;

  // --- Vertex subsample (front of the face) ---
  float sample_spacing_mm = 4.0f;   // model-XY grid cell; one vertex per cell
  int extra_samples_per_shape = 6;  // most-displaced vertices of every shape added
  float hole_margin_mm = 0.0f;      // no samples this close to the eye / mouth openings

  // --- Rigid ICP ---
  int icp_iterations = 6;
  float icp_first_gate_mm = 30.0f;  // association gate of the first iteration
  float icp_gate_mm = 10.0f;        // Tukey biweight cut-off afterwards
  float huber_mm = 2.5f;            // full weight below this
  // An ICP run stops early once a step rotates less than this and moves less than that: far
  // below the pose error (0.17 deg, 0.45 mm). eval track and 20 held-out occluder takes: the
  // same figures as 2e-5 rad / 0.01 mm to the third decimal; bench track's ICP stage 0.59 ->
  // 0.49 ms. 1e-3 rad / 0.1 mm saved another 0.05 ms but held-out take 1011 went 0.040 -> 0.056.
  float icp_converged_rad = 3e-4f;
  float icp_converged_mm = 0.05f;
  // Occlusion mask (see mark_occluded()): samples whose pixel or a pixel within
  // occluder_radius_px shows depth nearer than the model by occluder_margin_mm are hidden for
  // this frame (0 = no mask).
  float occluder_margin_mm = 40.0f;
  int occluder_radius_px = 5;
  // Landmarks under an occluder are dropped; above this fraction of the 51 inner points hidden,
  // all are.
  float max_hidden_landmark_fraction = 0.5f;
  // The face is reported occluded (TrackReport::occluded) on frames where the mask hides at
  // least this share of its samples facing the camera. A hand resting beside the face hides
  // its rim (the mask's radius): 0.05-0.09 on eval track's clutter takes, so 0.1 gave false
  // reports; a hand over the nose and mouth hides 0.3 or more.
  float occlusion_report_fraction = 0.2f;

  // --- Blendshape weights ---
  int weight_iterations = 2;  // IRLS rounds (re-association + robust weights)
  // ICP iterations between the frame's first IRLS round and the rest (0 = off; needs
  // weight_iterations >= 2): the pose is refined against the face with this frame's weights
  // (see track()). Together with temporal_weight 30 -> 50, eval track (5 seeds): occluder
  // worst frame 0.052 -> 0.033, pose 0.175 -> 0.173 deg, weight MAE 0.0102 unchanged; 20
  // held-out occluder takes: worst 0.118 -> 0.114, takes over 0.05 5 -> 3, mean 0.0123 ->
  // 0.0114. Costs the 2 ICP iterations, 0.16-0.18 ms a frame here (bench track: ICP stage
  // 0.45 -> 0.63 ms).
  int pose_refine_iterations = 2;
  // Robust weights of the depth rows: Tukey biweight with cut-off weight_tukey_k * sigma, sigma
  // from the median absolute residual of the frame (MAD), clamped to [weight_min_gate_mm,
  // icp_gate_mm]; weight_tukey_k = 0 uses the fixed icp_gate_mm.
  float weight_tukey_k = 4.685f;
  float weight_min_gate_mm = 3.0f;
  // mm^2 per unit weight change: lambda_t ||w - w_prev||^2. 30 -> 50 alone: held-out occluder
  // takes over 0.05 5 -> 4, weight MAE 0.0102 -> 0.0101; 80: 3 takes, but the default set's
  // take 1002 0.057 and, with the pose refinement, held-out weight MAE 0.0093 -> 0.0100.
  float temporal_weight = 50.0f;
  // Priors, in mm^2 against a data term of ~2000 samples. The L1 term keeps both shapes of an
  // opposing near-null pair (blink + wide, lookUp + lookDown, pucker + funnel) from turning on
  // together. The depth signal H_jj of a shape spans 10-300 mm^2 (lids, brows) to 1e3-1e5
  // (mouth, jaw), and the noise in its data gradient grows as sqrt(H_jj), so shape j's L1
  // weight is sparsity * (H_jj / median H)^sparsity_signal_power, with H_jj from this frame's
  // rows (a hidden region's shapes get none and are held by the temporal term) and the median
  // over the whole face: a constant one never let a lid shape turn on and biased a brow down
  // by sparsity / H_jj ~ 0.2. The shapes the L1 solve turned on are then solved again with
  // their L1 weight scaled by support_sparsity (relaxed lasso: the L1 term picks the shapes,
  // not their amplitude). The ridge stays small for the same reason (ridge 100 held a blink at
  // a third of its weight); it scales with the fraction of its signal a shape has this frame
  // (see stale_temporal_floor), so a hidden shape holds its value.
  // eval track, 5 seeds, with landmarks: constant L1 30 + ridge 20 -> this: weight MAE
  // 0.0178 -> 0.0139, on the takes' animated shapes 0.145 -> 0.101; occluder takes' unaffected
  // shapes, worst frame 0.396 -> 0.078 (L1 from the whole-face H_jj instead: 0.104, and an
  // occluded open mouth snapped shut, dragging the pose 1.4 deg).
  // The sparsity below scales with the frame's depth noise variance over
  // prior_noise_reference_mm^2 (the MAD of the residuals; ~0.7 mm on the usual sensor at 0.7 m),
  // never below 1 and at most max_prior_noise_scale. 0 = fixed. Block-correlated disparity
  // noise otherwise reads as small expressions (docs/tuning.md).
  float prior_noise_reference_mm = 0.75f;
  float max_prior_noise_scale = 4.0f;
  float sparsity = 60.0f;  // lambda_1 * sum w (w >= 0 makes it L1), for the median shape
  float sparsity_signal_power = 0.5f;
  float support_sparsity = 0.0f;  // 1 = plain lasso
  float ridge = 3.0f;             // lambda_r ||w||^2
  // Temporal weight of a shape whose region the previous frame hid (its signal then over its
  // whole-face signal), at least this fraction of temporal_weight (1 = always full): a region
  // coming out from under an occluder follows its data at once instead of easing back from
  // the value held while hidden (occluder takes: a blink held under the plate was 0.41 off
  // on the first frame out, 0.017 with 0.1).
  float stale_temporal_floor = 0.1f;
  // A shape that was on in the previous frame (weight above on_shape_min_weight) and whose
  // whole-face signal is below on_shape_max_signal x the median gets on_shape_sparsity x its
  // L1 weight: an expression under way is likely to continue. A brow or lid needs a data
  // gradient H_jj w > sparsity (H_jj / median)^0.5 to turn on, i.e. w > ~0.2, so without this a
  // brow at 0.25-0.3 flickered between 0 and its value from frame to frame, and on a frame
  // that hides most of the face it dropped to 0 and another shape took its motion (occluder
  // take 1026: browDown_L 0.27 -> 0, browInnerUp_L 0.23 instead). Not for the mouth and jaw,
  // whose L1 threshold is small anyway: there it let a combination of mouth shapes that
  // imitated a funnel hold on after the occluder left (take 1016, 18 frames to recover).
  // eval track, 5 seeds: weight MAE 0.0123 -> 0.0116, animated shapes 0.090 -> 0.078; 20
  // held-out occluder takes: worst frame 0.273 -> 0.114, the plate's own share 0.231 -> 0.066.
  float on_shape_sparsity = 0.25f;
  float on_shape_min_weight = 0.02f;
  float on_shape_max_signal = 1.0f;
  // Shapes whose depth signal (sum of squared point-to-plane rows) is below this fraction of
  // the median shape's get an extra prior of weak_shape_ridge * median signal. On the mean face
  // the weakest are eyeSquint (0.026), eyeWide (0.11) and eyeBlink (0.16); 0.1 held eyeWide at
  // 0 for most identities (take 1017: eyeWide_R 0.78, tracked 0.00 even without the plate).
  float weak_shape_fraction = 0.02f;
  float weak_shape_ridge = 2.0f;
  // The gaze shapes (eyeLook*) get the weak-shape prior whatever their signal: depth has no
  // eyeballs and the 68 landmarks no irises, so what these shapes move in the skin is the
  // lids, as eyeWide and eyeBlink do, and more of it (eyeLookUp 0.15 of the median signal,
  // eyeWide 0.11). Solved freely they take a lid's motion (take 1017: eyeWide_R 0.75 came out
  // as eyeLookUp_R 0.56). The stream reports them near 0. eval track, 5 seeds, together with
  // weak_shape_fraction 0.1 -> 0.02: weight MAE 0.0132 -> 0.0123, animated shapes 0.098 ->
  // 0.090.
  bool hold_gaze_shapes = true;
  // Antagonist pairs on one side of the face (browDown with browInnerUp and with browOuterUp,
  // eyeWide with eyeBlink and with eyeSquint) partly cancel each other, so the two switched on
  // together can stand in for one of them (occluder take 1026: browDown_L 0.3 read 0.47 with
  // browInnerUp_L 0.4 beside it, with the true identity too). A penalty mu w_a w_b with
  // mu = antagonist_weight sqrt(H_aa H_bb) (H with its priors) makes that cost. It adds to
  // H's off-diagonal, so positive definiteness is not guaranteed in general (the pair's own
  // 2x2 block stays so while |H_ab + mu| < sqrt(H_aa H_bb); an antagonist pair's data term
  // H_ab is negative, the shapes cancel); the solver is a bounded coordinate descent either
  // way, so the weights stay in [0, 1]. eval track, 5 seeds: weight MAE 0.0109 -> 0.0106; 20
  // held-out occluder takes: worst frame 0.169 -> 0.121, mean 0.0133 -> 0.0124.
  float antagonist_weight = 0.5f;
  // Samples the occlusion mask hides are imputed at the previous frame's weights: rows
  // n_i . B_i (w - w_prev) = 0 with this weight (0 = off). A shape mostly under the plate then
  // holds instead of following the few samples of its region still in view, which had pulled
  // it (occluder take 1027 without this: mouthSmile_L 0.68 read 1.0 under the plate) and, through
  // the samples it shares with them, the visible shapes. eval track, 5 seeds: occluder takes' mean
  // over the occluded frames 0.0068 -> 0.0066, worst frames 0.017 0.009 0.033 0.015 0.023 -> 0.015
  // 0.009 0.033 0.010 0.029; 20 held-out occluder takes: covered shapes' error 0.0182 ->
  // 0.0126, unoccluded 0.0114 -> 0.0104, takes over 0.05 4 -> 3, the plate's own share
  // 0.071 -> 0.063. 0.5 gives nearly the same (covered shapes 0.0129), 3 is worse (depth-only
  // weight MAE 0.0136 -> 0.0142: the mask also hides a few samples on unoccluded frames).
  float hidden_hold = 1.0f;
  float landmark_weight = 1.0f;  // mm^2 per px^2 of landmark residual
  float landmark_huber_px = 4.0f;
  // The per-axis landmark error landmark_weight and calibration_landmark_weight are set for
  // (eval track's truth landmarks: N(0, 1.5 px)). A source stating a larger error
  // (TrackLandmarks::noise_px) gets both scaled by (landmark_noise_px / noise_px)^2: least
  // squares weighs a row by 1 / sigma^2.
  float landmark_noise_px = 1.5f;
  // Calibration also measures where the landmarks sit on this face (see
  // calibrate_landmark_offsets()); offsets longer than this are not trusted (a longer one came
  // from an identity the calibration frames' view did not pin down; docs/tuning.md).
  bool calibrate_landmark_offsets = true;
  float max_landmark_offset_mm = 4.0f;
  // A landmark's offset is measured in 3D where the frame has depth at the detected point within
  // this of the model's landmark (the point lifted onto the measured surface); else on the ray at
  // the model's depth. 0 = always the model's depth.
  float landmark_offset_depth_gate_mm = 8.0f;
  // The same for the depth samples: the mean point-to-plane residual of each sample over the
  // calibration frames (neutral face) moves that sample along its normal, so what the identity
  // PCA cannot fit of this face (and its prior shrinks) does not pull the expression weights.
  // Samples seen on fewer than half the frames keep none; offsets are clamped to the maximum.
  // Occluder take 1002: browDown_R stood at 0.1-0.2 (truth 0) for 50 frames, with the plate and
  // without; with the true identity loaded it did not. eval track, 5 seeds: weight MAE 0.0116
  // -> 0.0109, occluder worst frame 0.151 -> 0.068; 20 seeds: 0.0077 -> 0.0067.
  bool calibrate_depth_offsets = true;
  float max_depth_offset_mm = 3.0f;

  // Diagnostics: report each weight's data-only standard error (TrackReport::weight_sigma),
  // the Cramer-Rao bound of the frame's weight solve without its priors. Costs an inversion of
  // the 53 x 53 information matrix a frame (bench track, depth only: 1.41 -> 1.46-1.50 ms);
  // eval track turns it on for its occluder takes.
  bool report_weight_sigma = false;

  // --- Loss detection ---
  int min_inliers = 150;
  float min_inlier_fraction = 0.35f;  // of the samples facing the camera inside the image
  float max_rms_mm = 4.0f;
  // Before calibration the model is the mean face, which fits an atypical face only to 4-5 mm
  // (30 identities: candidate fits up to 5.1 mm, 90th percentile 4.8). Under the tracking bound
  // occluder take 1013's subject (4.1-4.5 mm) was not acquired for 40 frames and was then
  // calibrated well into an expression: mouthUpperUp_R 0.85, jawRight 0.8 and mouthPress_L 0.85
  // read 0 for the rest of the take (worst frame 0.074 -> 0.039 with this bound). It applies
  // only on frames with landmarks (a detector's confirmation that this is a face): depth alone
  // cannot tell a face at 5 mm from a head-sized ellipsoid.
  float uncalibrated_max_rms_mm = 6.0f;

  // --- Calibration ---
  int calibration_frames = 10;
  // Gauss-Newton rounds of the joint identity + calibration-pose fit; the identity is the mean
  // of the second half's iterates. It runs once per subject (bench track: calibration_ms).
  int calibration_rounds = 24;
  int identity_modes = 100;      // leading identity PCA modes fitted
  float identity_prior = 20.0f;  // mm^2 per unit coefficient^2 (coefficients are in sigma)
  // The identity fit also reprojects the calibration frames' landmarks (mm^2 per px^2, Huber
  // landmark_huber_px; 0 = depth only). Depth hardly sees a lip or a lid slide along the face:
  // occluder take 1041's subject came out with the lower lip 13 mm high (its landmarks 10 px
  // off), so mouthLowerDown read 1.0 on a neutral face (take weight MAE 0.069; with the true
  // identity 0.006, with this 0.0065). eval track, 5 seeds: weight MAE 0.0106 -> 0.0102,
  // absolute pose 0.534 -> 0.424 deg; 40 takes 1030-1069: take weight MAE 0.0097 -> 0.0088,
  // absolute pose 0.51 -> 0.41 deg. Calibration 475 -> 536 ms.
  float calibration_landmark_weight = 1.0f;
  // Calibration fits the identity with the rigid part of its modes removed (depth cannot tell
  // it from pose); true keeps the fitted coefficients' rigid part in the final face: the PCA
  // modes tie it to their shape, so it predicts the true face frame (absolute pose error
  // 1.98 -> 0.94 deg, 2.72 -> 1.59 mm over 5 seeds; relative figures unchanged).
  bool keep_identity_rigid = true;

  // --- Acquisition (first frame and after loss) ---
  int acquire_iterations = 20;
  float acquire_band_mm = 120.0f;  // the face: pixels within this of the nearest surface
  // A start pose is accepted only with inliers >= this fraction of all samples and RMS below
  // acquire_max_rms_mm once calibrated (before: max_rms_mm, or uncalibrated_max_rms_mm with
  // landmarks) and, with landmarks, the model's landmarks within acquire_landmark_px of them
  // (median). The fitted face must also reach acquire_max_rms_mm on its own calibration frames
  // (mean), or calibration starts over: a lock at a wrong pose (an atypical face, 24 deg off)
  // otherwise calibrated and tracked 38 deg off.
  float acquire_min_sample_fraction = 0.35f;
  float acquire_max_rms_mm = 2.0f;
  float acquire_landmark_px = 12.0f;

  PoseFilterOptions pose_filter;
};

enum class TrackState : std::uint8_t {
  kSearching,    // no face yet (or still lost): outputs hold the last good values
  kCalibrating,  // tracking with the provisional identity while collecting calibration frames
  kTracking,
  kRecovered,  // tracking again after loss on this frame
  kLost,       // the face was lost on this frame (report + keep the last good values)
  kBadInput,   // wrong size or no valid depth at all
};
const char* to_string(TrackState state);

// The gaze shapes (eyeLook*): they turn the eyeballs, which depth does not see (see
// TrackerOptions::hold_gaze_shapes).
inline bool is_gaze_shape(std::string_view name) {
  return name.starts_with("eyeLook");
}

// Optional 2D landmarks: the 68 iBUG points in DEPTH image pixels (detect on colour, map
// through the registration); `valid[i] == 0` drops point i. Contour points 0-16 are ignored
// (they slide along the silhouette).
struct TrackLandmarks {
  std::span<const Eigen::Vector2f> points;
  std::span<const std::uint8_t> valid;  // empty = all valid
  // The source's typical error, px rms per image axis (0 = TrackerOptions::landmark_noise_px):
  // the landmark rows count (landmark_noise_px / noise_px)^2 as much.
  float noise_px = 0.0f;
};

// A subject's personal blendshape rig in the face model's topology (storage's RigData seen
// through spans, so algo/ does not depend on storage/).
struct TrackerRig {
  std::span<const float> neutral;  // 3 * model.vertex_count, model frame, mm
  // (model fitting-shape index, full shape positions of 3 * vertex_count floats)
  std::vector<std::pair<int, std::span<const float>>> shapes;
};

// Blendshapes that depend on who is tracked. In a bilinear model (FaceWarehouse eq. 10,
// V = C x_2 w_id x_3 w_exp) every subject has their own expression deltas, so once calibration
// has fitted the identity the tracker asks this source for the subject's deltas instead of
// keeping the model's fixed ones (issue 6: "fit identity ... and build their blendshapes").
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
  // With TrackerOptions::report_weight_sigma: each weight's standard error from this frame's
  // data alone (no priors; given the pose), +inf for a shape the data does not see; else 0.
  std::array<float, kMaxTrackedShapes> weight_sigma{};
  int samples_used = 0;  // samples with a depth correspondence
  int inliers = 0;       // of those, within the Tukey cut-off
  float rms_mm = 0.0f;   // point-to-plane RMS of the inliers
  int landmarks_used = 0;
  int calibration_frames_left = 0;
  // Occlusion as data: the share of the face's samples (facing the camera, inside the image)
  // the occlusion mask hides on this frame, and whether it is at least
  // TrackerOptions::occlusion_report_fraction. Frames that measure nothing (searching after a
  // loss) hold the last values; the weights of the shapes under the occluder are held too
  // (TrackerOptions::hidden_hold).
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
