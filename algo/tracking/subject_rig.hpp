// The subject's landmark and blendshape rig at the tracker's samples (an object, in InfiniTAM's
// sense: data the engines read). The samples are a fixed subsample of the front of the face;
// the subject's blendshapes (identity face + expression deltas) are precomputed there once per
// subject, so a frame only streams a 3N x K matrix. Also holds the current face (base + B w)
// and the per-shape depth signal the weight solver's priors scale with.
//
// Units mm, model frame (+X subject's left, +Y up, +Z out of the face).
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "algo/core/result.hpp"
#include "algo/core/rigid_pose.hpp"
#include "algo/facemodel/face_model.hpp"
#include "algo/tracking/bounded_lsq.hpp"
#include "algo/tracking/track_types.hpp"
#include "algo/tracking/tracker_options.hpp"

namespace fb {

using RowMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using ColMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::ColMajor>;

struct SubjectRig {
  using Twist = Eigen::Matrix<float, 6, 1>;

  // Selects the samples on the model's mean face and builds the identity-independent bases;
  // the rig is then the mean face. `model` must outlive the rig.
  static Result<SubjectRig> create(const FaceModel& model, const RigSampleOptions& samples,
                                   const WeightSolverOptions& priors, int identity_modes);

  // The rig of identity `coefficients` (sigma units), minus the linearised rigid motion
  // `rigid_offset` of its modes (see rigid_of_mode).
  void build(std::span<const float> coefficients, const ShapeVector& weights,
             const Twist& rigid_offset = Twist::Zero());
  // The rest of build() once mesh_scratch holds the subject's neutral (full mesh).
  void finish(const ShapeVector& weights);
  // A stored rig: its neutral and its shapes' deltas (identity all zeros).
  Result<void> load(const TrackerRig& rig, const ShapeVector& weights);
  void use_model_expressions() {
    if (!custom_rig) return;
    expression_at_samples = model_expression_at_samples;
    expression_at_landmarks = model_expression_at_landmarks;
    custom_rig = false;
  }
  // With a subject_blendshapes source: its deltas for `identity` (mesh_scratch holds that
  // identity's neutral).
  void build_subject_blendshapes(const ShapeVector& weights);
  void update_current(const ShapeVector& weights) {
    // current = base + B w over the shapes with w_j != 0 (w >= 0 with an L1 prior: most are
    // exactly 0, and the others add exactly what the full product adds, up to rounding).
    current = base;
    for (int j = 0; j < k; ++j) {
      if (weights[j] != 0.0f) current.noalias() += weights[j] * expression_at_samples.col(j);
    }
    landmark_current = landmark_base;
    landmark_current.noalias() += expression_at_landmarks * weights;
  }

  Eigen::Vector3f sample(int i) const { return current.segment<3>(3 * i); }
  // Sample i's point x and normal nn in the camera frame under pose p; false when it faces away
  // from the camera or grazes it (depth there is unreliable).
  bool facing_sample(const RigidPoseF& p, int i, Eigen::Vector3f& x, Eigen::Vector3f& nn) const {
    x = p.r * sample(i) + p.t;
    nn = p.r * normals[static_cast<std::size_t>(i)];
    return x.z() > 1.0f && nn.dot(x) <= -0.2f * x.norm();
  }
  // Landmark l of the current face in the camera frame at pose p.
  Eigen::Vector3f landmark_in_camera(const RigidPoseF& p, int l) const {
    return p.r * landmark_current.segment<3>(3 * l) + p.t;
  }

  const FaceModel* model = nullptr;  // non-owning
  int k = 0;                         // fitting shapes
  int n = 0;                         // samples
  int modes = 0;                     // identity modes fitted
  // The shape priors' options (WeightSolverOptions), which finish() turns into shape_ridge.
  float ridge = 0.0f, weak_shape_fraction = 0.0f, weak_shape_ridge = 0.0f;
  bool hold_gaze_shapes = true;

  std::vector<std::uint32_t> sample_vertices;
  // Identity-independent: expression deltas and identity modes at the samples (3n x k, 3n x m).
  // The deltas by column: update_current() adds only the shapes with a non-zero weight.
  ColMatrix expression_at_samples;
  RowMatrix identity_at_samples;
  RowMatrix expression_at_landmarks;  // 3*68 x k
  RowMatrix identity_at_landmarks;    // 3*68 x m
  // The model's own expression deltas; a stored rig (load) replaces the two above.
  ColMatrix model_expression_at_samples;
  RowMatrix model_expression_at_landmarks;
  bool custom_rig = false;
  const SubjectBlendshapes* subject_blendshapes = nullptr;  // FaceTracker::set_subject_blendshapes
  // Rigid part of each identity mode at the samples ([omega; t] about `rigid_pivot`, 6 x m),
  // removed from the calibration basis: depth of the front of the face cannot tell a head
  // rotated by a degree from a differently shaped head, so calibrated identities carry no
  // rigid motion and the pose is determined by the data alone.
  Eigen::Matrix<float, 6, Eigen::Dynamic> rigid_of_mode;
  Eigen::Vector3f rigid_pivot = Eigen::Vector3f::Zero();

  // The subject (rebuilt by build()).
  std::vector<float> identity;           // m coefficients
  Eigen::VectorXf base;                  // 3n: neutral + identity at the samples
  std::vector<Eigen::Vector3f> normals;  // n, model frame, of the identity neutral
  RowMatrix normal_rows;                 // n x k: n_i^T B_i (point-to-plane rows)
  Eigen::VectorXf landmark_base;         // 3*68, with landmark_offset
  // The subject's landmark offsets (model frame, 3*68), measured while calibrating: where the
  // detector puts each point on this face relative to the model's landmark vertex.
  Eigen::VectorXf landmark_offset;
  Eigen::Vector3f centroid = Eigen::Vector3f::Zero();  // of the samples, model frame
  float nose_z = 0.0f;                                 // largest model z of the samples
  ShapeVector shape_ridge;     // per-shape Tikhonov weight (mm^2), see finish()
  float signal_median = 1.0f;  // median depth signal H_jj of the shapes over the whole face
  ShapeVector full_signal;     // per shape: H_jj over the whole face
  ShapeVector seen_fraction;   // per shape: the last frame's H_jj / full_signal (clamped to 1)
  std::vector<int> weak_shapes;
  std::vector<std::uint8_t> gaze_shape;          // per shape: an eyeLook* (gaze) shape
  std::vector<std::pair<int, int>> antagonists;  // WeightSolverOptions::antagonist_weight

  // The current face.
  Eigen::VectorXf current;           // 3n: base + B w
  Eigen::VectorXf landmark_current;  // 3*68

  std::vector<float> mesh_scratch;  // full-mesh neutral of the subject
  std::vector<Eigen::Vector3f> mesh_normals;
};

}  // namespace fb
