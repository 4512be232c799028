// The blendshape weight solve (an engine with its buffers): weights in [0, 1] by bounded least
// squares (bounded_lsq.hpp) on the point-to-plane rows of the depth samples and the
// reprojection rows of the 2D landmarks, with IRLS robust weights (Tukey, MAD scale), a temporal
// term, L1 and ridge priors scaled by each shape's depth signal, an antagonist penalty and the
// hidden samples imputed at the previous weights. On request it reports each weight's data-only
// standard error (weight_standard_errors). Steady state: no allocation.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "algo/core/image.hpp"
#include "algo/core/rigid_pose.hpp"
#include "algo/tracking/bounded_lsq.hpp"
#include "algo/tracking/occlusion_mask.hpp"
#include "algo/tracking/subject_rig.hpp"
#include "algo/tracking/tracker_geometry.hpp"
#include "algo/tracking/tracker_options.hpp"

namespace fb {

// How well one frame's data pins each weight down: sigma_j = sqrt((I^-1)_jj), with I the Fisher
// information of the weights (sum over the frame's rows of J^T J / sigma_row^2; the Cramer-Rao
// bound given the pose, without priors), inverted over the shapes the data sees at all
// (I_jj > min_information); the others get +inf. A brow seen by depth alone has ~0.1, a jaw
// ~0.01. Fixed maximum size: no allocation.
void weight_standard_errors(const ShapeMatrix& information, float min_information,
                            ShapeVector& sigma);

class WeightSolver {
 public:
  // `max_gate_mm`: the upper clamp of the robust cut-off (RigidIcpOptions::icp_gate_mm).
  void allocate(const WeightSolverOptions& options, float max_gate_mm, int n, int k);
  // `iterations` IRLS rounds at pose p, updating `weights` and the rig's current face; the
  // frame's last solve (final) records each shape's seen fraction for the next frame.
  void solve(SubjectRig& rig, const TrackerCamera& camera, const OcclusionMask& mask,
             const Image<float>& image, const PixelRect& b, const RigidPoseF& p, int iterations,
             bool final, const TrackLandmarks* landmarks, int& landmarks_used);
  const WeightSolverOptions& options() const { return options_; }

  ShapeVector weights;           // the current solution
  ShapeVector previous_weights;  // last frame's output
  // With WeightSolverOptions::report_weight_sigma: from the frame's last solve.
  ShapeVector weight_sigma;

 private:
  // The depth rows of one IRLS round into rows / targets; returns their count and sets
  // noise_sigma (the MAD estimate, 0 when not measured).
  int add_depth_rows(const SubjectRig& rig, const TrackerCamera& camera, const OcclusionMask& mask,
                     const Image<float>& image, const PixelRect& b, const RigidPoseF& p,
                     float& noise_sigma);
  // The landmark rows after the first `count`; returns the new count.
  int add_landmark_rows(const SubjectRig& rig, const TrackerCamera& camera,
                        const OcclusionMask& mask, const RigidPoseF& p,
                        const TrackLandmarks& landmarks, int count, int& landmarks_used);
  // The hidden samples' imputation rows after the first `count`; returns how many.
  int add_hidden_rows(const SubjectRig& rig, const OcclusionMask& mask, const RigidPoseF& p,
                      int count);
  // Priors, temporal term and antagonist penalty into h and g.
  void add_priors(SubjectRig& rig, float noise_sigma, bool last_solve, bool hidden_rows);
  // From the frame's last solve: its depth rows [0, depth_rows) with noise depth_sigma_mm, then
  // its landmark rows.
  void estimate_weight_sigma(const SubjectRig& rig, int depth_rows, int landmark_rows,
                             float depth_sigma_mm);

  WeightSolverOptions options_;
  float max_gate_mm_ = 10.0f;
  RowMatrix rows;  // (n + 2*68) x k
  Eigen::VectorXf targets;
  std::vector<int> found_sample;      // n: samples with a depth correspondence this round
  std::vector<float> found_residual;  // their point-to-plane residuals (model frame)
  std::vector<float> found_target;    // n_i . (q - base_i)
  std::vector<float> abs_scratch;     // |residual| for the median
  ShapeMatrix h;
  ShapeVector g;
  ShapeMatrix h_hidden;        // imputed rows of the hidden samples
  ShapeVector shape_sparsity;  // per-shape L1 weight (mm^2) of the frame
  // report_weight_sigma: the frame's Fisher information.
  ShapeMatrix information;
  ShapeMatrix landmark_gram;
};

}  // namespace fb
