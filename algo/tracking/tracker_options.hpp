// The tracker's options, one group per room (depth smoother, subject rig, rigid ICP, occlusion
// mask, weight solver, loss test, calibrator, acquisition). Comments say why an option exists;
// the figures that chose each value are in docs/tuning.md. The names are the `--set KEY=V`
// keys of `eval track` / `bench track` (sim/scoring/take_runner.cpp).
#pragma once

#include "algo/tracking/pose_filter.hpp"

namespace fb {

// Depth preprocessing (depth_smoother.hpp).
struct DepthSmootherOptions {
  // Temporal: weighted mean of the last k frames per pixel (wrinkle paper: k = 5). Older frames
  // count only where they agree with the newest within temporal_range_mm, so motion does not
  // smear.
  int temporal_frames = 5;
  float temporal_range_mm = 4.0f;
  float temporal_decay = 0.7f;  // weight of frame age a: decay^a
  // Spatial, after the temporal mean (KinectFusion filters raw depth the same way): mean over
  // the (2r+1)^2 neighbours within spatial_range_mm of the centre pixel, so depth edges (eye
  // and mouth openings, the silhouette) do not blur. 0 = off.
  int spatial_radius_px = 1;
  float spatial_range_mm = 3.0f;
  float min_depth_mm = 400.0f;
  float max_depth_mm = 2000.0f;
};

// The vertex subsample of the front of the face the tracker fits (subject_rig.hpp).
struct RigSampleOptions {
  float sample_spacing_mm = 4.0f;   // model-XY grid cell; one vertex per cell
  int extra_samples_per_shape = 6;  // most-displaced vertices of every shape, so small ones show
  float hole_margin_mm = 0.0f;      // no samples this close to the eye / mouth openings
};

// Rigid projective point-to-plane ICP (rigid_icp.hpp).
struct RigidIcpOptions {
  int icp_iterations = 6;
  float icp_first_gate_mm = 30.0f;  // association gate of the first iteration
  float icp_gate_mm = 10.0f;        // Tukey biweight cut-off afterwards
  // A run stops early once a step rotates and moves less than this: far below the pose error
  // (0.17 deg, 0.45 mm), so the figures do not move and the ICP stage gets cheaper.
  float icp_converged_rad = 3e-4f;
  float icp_converged_mm = 0.05f;
};

// The occlusion mask (occlusion_mask.hpp) and what the report calls an occluded face.
struct OcclusionMaskOptions {
  // Samples whose pixel, or a pixel occluder_radius_px away, shows depth nearer than the model
  // by occluder_margin_mm are hidden for the frame (0 = no mask). The margin is above the
  // face's own relief, so the face never hides itself.
  float occluder_margin_mm = 40.0f;
  int occluder_radius_px = 5;
  // Landmarks under an occluder are dropped; above this fraction of the 51 inner points hidden,
  // all are (a shape predictor places its points jointly).
  float max_hidden_landmark_fraction = 0.5f;
  // TrackReport::occluded from this share of the face's camera-facing samples hidden. A hand
  // resting beside the face hides its rim (0.05-0.09); a hand over nose and mouth 0.3 or more.
  float occlusion_report_fraction = 0.2f;
};

// The blendshape weight solve (weight_solver.hpp): bounded least squares on the depth rows and
// landmark rows with robust weights, temporal smoothness and priors, in mm^2 against a data term
// of ~2000 samples.
struct WeightSolverOptions {
  int weight_iterations = 2;  // IRLS rounds (re-association + robust weights)
  // ICP iterations between the frame's first IRLS round and the rest (0 = off; needs
  // weight_iterations >= 2): where a shape moves little depth, the pose takes part of the
  // expression change; refining the pose against this frame's weights splits them again.
  int pose_refine_iterations = 2;
  // Tukey cut-off weight_tukey_k * sigma, sigma the MAD of the frame's residuals, clamped to
  // [weight_min_gate_mm, icp_gate_mm]: an occluder's samples and its ragged rim get zero weight,
  // the clean face full weight. 0 = the fixed icp_gate_mm.
  float weight_tukey_k = 4.685f;
  float weight_min_gate_mm = 3.0f;
  float temporal_weight = 50.0f;  // mm^2 per unit weight change: lambda_t ||w - w_prev||^2
  // The L1 weight scales with the frame's noise variance over prior_noise_reference_mm^2, in
  // [1, max_prior_noise_scale] (0 = fixed): block-correlated disparity noise otherwise reads as
  // small expressions.
  float prior_noise_reference_mm = 0.75f;
  float max_prior_noise_scale = 4.0f;
  // L1 weight of shape j: sparsity * (H_jj / median H)^sparsity_signal_power, H_jj this frame's
  // depth signal of the shape: the noise in a shape's data gradient grows as sqrt(H_jj), and a
  // constant weight never let a lid turn on. It keeps opposing near-null pairs (blink + wide)
  // from turning on together. The shapes it turned on are solved again with the L1 weight
  // scaled by support_sparsity (relaxed lasso: L1 picks the shapes, not their amplitude).
  float sparsity = 60.0f;
  float sparsity_signal_power = 0.5f;
  float support_sparsity = 0.0f;  // 1 = plain lasso
  // lambda_r ||w||^2, small (a large ridge holds a blink down); it scales with the share of its
  // signal a shape has this frame, so a hidden shape holds its value.
  float ridge = 3.0f;
  // The temporal weight of a shape the previous frame hid is that frame's share of its signal,
  // at least this fraction: a region coming out from under an occluder follows its data at
  // once instead of easing back from the held value.
  float stale_temporal_floor = 0.1f;
  // A shape on in the previous frame (weight > on_shape_min_weight) with a whole-face signal
  // below on_shape_max_signal x the median gets on_shape_sparsity x its L1 weight: an
  // expression under way is likely to continue, and a brow at 0.25 no longer flickers to 0. Not
  // for the mouth and jaw (their L1 threshold is small anyway; there it held stand-ins on).
  float on_shape_sparsity = 0.25f;
  float on_shape_min_weight = 0.02f;
  float on_shape_max_signal = 1.0f;
  // Shapes whose depth signal is below weak_shape_fraction of the median shape's get an extra
  // prior of weak_shape_ridge * median signal: nearly invisible in depth, they wander on noise.
  float weak_shape_fraction = 0.02f;
  float weak_shape_ridge = 2.0f;
  // The gaze shapes (eyeLook*) get the weak-shape prior whatever their signal: depth has no
  // eyeballs and the 68 landmarks no irises, so what they move is the lids, and solved freely
  // they take a lid's motion.
  bool hold_gaze_shapes = true;
  // Antagonist pairs on one side (browDown with browInnerUp / browOuterUp, eyeWide with eyeBlink
  // / eyeSquint) partly cancel, so the two on together can stand in for one. A penalty
  // mu w_a w_b, mu = antagonist_weight sqrt(H_aa H_bb), makes that cost; the solver is a bounded
  // coordinate descent, so the weights stay in [0, 1] even if H loses definiteness.
  float antagonist_weight = 0.5f;
  // Samples under the occlusion mask are imputed at the previous weights, rows
  // n_i . B_i (w - w_prev) = 0 with this weight (0 = off): a shape mostly under an occluder
  // holds instead of following the few samples of it still in view.
  float hidden_hold = 1.0f;
  float landmark_weight = 1.0f;  // mm^2 per px^2 of landmark residual
  float landmark_huber_px = 4.0f;
  // The per-axis landmark error landmark_weight and calibration_landmark_weight are set for;
  // a source stating a larger error (TrackLandmarks::noise_px) gets both scaled by
  // (landmark_noise_px / noise_px)^2, as least squares weighs a row by 1 / sigma^2.
  float landmark_noise_px = 1.5f;
  // TrackReport::weight_sigma: each weight's data-only standard error (Cramer-Rao bound without
  // the priors). Costs an inversion of the K x K information matrix a frame.
  bool report_weight_sigma = false;
};

// When a fit counts as the face (the loss test).
struct LossOptions {
  int min_inliers = 150;
  float min_inlier_fraction = 0.35f;  // of the samples facing the camera inside the image
  float max_rms_mm = 4.0f;
  // Before calibration the model is the mean face, which fits an atypical face only to 4-5 mm;
  // with landmarks (a detector's confirmation that this is a face) the bound is this looser one.
  // Depth alone cannot tell a face at 5 mm from a head-sized ellipsoid.
  float uncalibrated_max_rms_mm = 6.0f;
};

// Calibration: the subject's identity from the first frames (calibrator.hpp).
struct CalibratorOptions {
  int calibration_frames = 10;
  // Gauss-Newton rounds of the joint identity + calibration-pose fit; the identity is the mean
  // of the second half's iterates (the projective association makes them circle the minimum).
  int calibration_rounds = 24;
  int identity_modes = 100;      // leading identity PCA modes fitted
  float identity_prior = 20.0f;  // mm^2 per unit coefficient^2 (coefficients are in sigma)
  // The identity fit also reprojects the calibration frames' landmarks (mm^2 per px^2, Huber
  // landmark_huber_px; 0 = depth only): depth hardly sees a lip or a lid slide along the face.
  float calibration_landmark_weight = 1.0f;
  // The identity is fitted with the rigid part of its modes removed (depth cannot tell it from
  // pose); true keeps the fitted coefficients' rigid part in the final face, whose shape then
  // predicts the true face frame (absolute pose).
  bool keep_identity_rigid = true;
  // Where the landmarks sit on this face (see Calibrator::landmark_offsets()); longer offsets
  // are not trusted (they came from an identity the calibration view did not pin down).
  bool calibrate_landmark_offsets = true;
  float max_landmark_offset_mm = 4.0f;
  // A landmark's offset is measured where the frame has depth within this of the model's
  // landmark (on the measured surface), else on the ray at the model's depth. 0 = always that.
  float landmark_offset_depth_gate_mm = 8.0f;
  // The same for the depth samples: each sample's mean residual over the calibration frames
  // moves it along its normal, so what the identity PCA cannot fit of this face does not pull
  // the expression weights. Clamped to the maximum.
  bool calibrate_depth_offsets = true;
  float max_depth_offset_mm = 3.0f;
};

// Acquisition: the first frame and after a loss (face_tracker_acquire.cpp).
struct AcquireOptions {
  int acquire_iterations = 20;
  float acquire_band_mm = 120.0f;  // the face: pixels within this of the nearest surface
  // A start pose is accepted only with inliers >= this fraction of all samples, an RMS below
  // acquire_max_rms_mm once calibrated and, with landmarks, the model's landmarks within
  // acquire_landmark_px of them (median). A calibration whose face does not reach
  // acquire_max_rms_mm on its own frames starts over: a lock at a wrong pose would otherwise
  // calibrate and track degrees off.
  float acquire_min_sample_fraction = 0.35f;
  float acquire_max_rms_mm = 2.0f;
  float acquire_landmark_px = 12.0f;
};

struct TrackerOptions {
  DepthSmootherOptions depth;
  RigSampleOptions samples;
  RigidIcpOptions icp;
  OcclusionMaskOptions occlusion;
  WeightSolverOptions weights;
  LossOptions loss;
  CalibratorOptions calibration;
  AcquireOptions acquire;
  PoseFilterOptions pose_filter;
};

}  // namespace fb
