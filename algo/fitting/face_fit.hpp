// Fitting the face model to one capture (FaceWarehouse sections 3.2.1-3.2.2): a fused depth map
// in the depth camera plus 68 landmarks -> a mesh in the model's topology.
//
//   neutral, step 1: PCA morphable fit + rigid pose, E1 = 2 Efea + 0.5 Epos + 1 Ecoef, a few
//                    rounds of least squares with contour and closest-point updates; broad
//                    offsets along the normal solved with the modes (offset_basis.hpp);
//   neutral, step 2: Laplacian refinement E2 = 0.5 Efea + Epos + Elap (cotangent Laplacian,
//                    length-preserving target), inexact Gauss-Newton with one factorization
//                    (refine_system.hpp);
//   expressions:     the fitted neutral moved as G0 -> Gi (the model's own shapes added, or
//                    deformation transfer: ExpressionStart), rigid alignment, each recipe part
//                    scaled to the capture, then the same refinement with that capture's
//                    landmarks and the subject's shared factorization.
//
// Units mm, camera frame = the depth camera (OpenCV axes). Landmarks are given in the depth
// image (algo/landmarks converts colour-image detections and lifts interior points).
#pragma once

#include <array>
#include <optional>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "algo/core/camera_model.hpp"
#include "algo/core/image.hpp"
#include "algo/core/result.hpp"
#include "algo/facemodel/face_model.hpp"
#include "algo/fitting/offset_basis.hpp"
#include "algo/fitting/refine_system.hpp"

namespace fb {

inline constexpr int kFitLandmarkCount = 68;
// iBUG 0-16 are the face contour: 2D only, their mesh vertex slides along the silhouette.
inline constexpr bool is_contour_landmark(int i) {
  return i >= 0 && i <= 16;
}

struct FitLandmark {
  bool valid = false;
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();  // depth image, px
  // Camera-frame 3D point for interior landmarks (lifted from depth); unset = use 2D only.
  std::optional<Eigen::Vector3d> point;
};

// What a fit matches: a depth map (e.g. ray-cast from the fused volume) and its landmarks.
struct FitTarget {
  PinholeIntrinsics intrinsics;
  Image<float> depth_mm;           // z in mm, 0 = no data
  Image<Eigen::Vector3f> normals;  // optional; computed from depth when empty
  // Optional, [0, 1] per depth pixel: how far the take's frames agreed there
  // (algo/fusion/view_consistency.hpp). The refinement's depth term is weighted by it, so hair,
  // beard and the rims of the eyes and mouth are held by the Laplacian rather than chased; the
  // PCA step (step 1) does not use it (docs/tuning.md: it cost vertex error). Empty = all 1.
  Image<float> confidence;
  // Optional, [0, 1] per depth pixel: how skin-like the registered colour is
  // (algo/landmarks/skin_map.hpp). Where it is under 0.5 (hair, a beard) the depth is taken
  // as a bound: the face lies on or behind it. Empty = all skin.
  Image<float> skin;
  std::array<FitLandmark, kFitLandmarkCount> landmarks;
  // The mesh vertex each landmark marks when the landmarks follow a detector's convention
  // rather than the model's (dlib: algo/facemodel/landmark_embedding.hpp); unset = the model's
  // landmark_vertices. The contour (0-16) slides along the silhouette either way.
  std::optional<std::array<std::uint32_t, kFitLandmarkCount>> landmark_vertices;
};

// Fills target.normals from target.depth_mm (central differences, unit, towards the camera),
// or keeps the given ones but clears them on silhouettes and the rims of holes, and checks the
// target: sizes, enough depth in the landmarks' region, enough landmarks.
// Errors say what is missing ("no face landmarks", "no depth in the face region").
Result<void> prepare_fit_target(FitTarget& target);

// Lifts a depth-image point to 3D: bilinear depth where the 2x2 neighbourhood is one surface,
// else (unless `strict`) the lower quartile of valid depth within `radius_px`; nullopt where
// there is no depth. Landmark lifting is strict: a point on the rim of an eye or the mouth
// (depth jumps there) stays 2D rather than take the depth of the wrong side.
std::optional<Eigen::Vector3d> lift_depth(const Image<float>& depth, const PinholeIntrinsics& k,
                                          const Eigen::Vector2d& px, int radius_px = 2,
                                          bool strict = false);
// The same with the target's own depth. Used for operator corrections (strict).
std::optional<Eigen::Vector3d> lift_with_depth(const FitTarget& target, const Eigen::Vector2d& px,
                                               int radius_px = 2, bool strict = false);

struct RefineOptions {
  // E2 = w_fea Efea + w_pos Epos + w_lap Elap (paper: 0.5, 1, 1). Our Epos sums over ~5k
  // vertices at Kinect density; with the paper's 0.5 a 1 px landmark error pulled the refined
  // face measurably (vertex error 0.42 -> 0.63 mm on rendered depth), with 0.1 -> 0.52 mm.
  double w_fea = 0.1;
  double w_pos = 1.0;
  double w_lap = 1.0;
  double landmark_huber_mm = 3.0;    // landmark pulls are capped at this distance
  int iterations = 12;               // inexact Gauss-Newton steps, one factorization
  int margin_rings = 2;              // free vertices around the fitting region (refine_system.hpp)
  int reassociate_every = 1;         // closest points are re-found every k steps
  double max_distance_mm = 6.0;      // depth correspondence gate
  double max_normal_angle_deg = 70;  // between the vertex normal and the depth normal
  // Cauchy weight on the point-to-plane residual: a sample this far off pulls half as hard, so
  // outliers (a fold into a hole, a hair strand) do not drag the surface.
  double robust_scale_mm = 3.0;
};

struct NeutralFitOptions {
  // E1 = w_fea Efea + w_pos Epos + w_coef Ecoef (paper: 2, 0.5, 1). Measured on rendered
  // depth with 1 px landmark noise: w_fea 2 -> 1.05 mm vertex error, 0.5 -> 0.42 mm (landmark
  // noise then dominates the tangential placement), so the default deviates from the paper.
  double w_fea = 0.5;
  // The landmark weight falls to this over the gate's schedule: the landmarks bring the face
  // into the basin, the depth then places it (a detector's points are 2-4 px off).
  double w_fea_final = 0.06;
  double w_pos = 0.5;
  double w_coef = 1.0;
  double landmark_huber_mm = 3.0;  // Huber loss on landmark residuals (robust to wrong points)
  int rounds = 7;                  // rounds over which the depth gate shrinks (paper: 5-8)
  // Then more rounds at the final gate until the step settles: a face far from the mean
  // (identity modes past 3 sigma) is still moving after the schedule (docs/tuning.md).
  int max_rounds = 20;
  double settled_coeff = 0.01;     // largest identity-coefficient step (sigma units) ...
  double settled_mm = 0.02;        // ... and translation step that count as settled
  int identity_modes = 100;        // leading modes used (<= model.identity_count)
  int depth_vertex_stride = 2;     // every k-th fitting vertex takes part in Epos in step 1
  double max_distance_mm = 15.0;   // depth gate of the first round, shrinking to
  double final_distance_mm = 6.0;  // this by the last round
  double max_normal_angle_deg = 70;
  // Depth on hair or a beard (FitTarget::skin) pushes a face in front of it back at full
  // weight and pulls one behind it at this weight where it lies along the face
  // (fit_correspondence.hpp): how thick the hair is is not known.
  double hair_weight = 0.5;
  // Cauchy scale of the depth residual in step 1: depth the identity space cannot hold (hair
  // the skin map missed, this person's own bumps) pulls the whole face less (0 = plain squares).
  double robust_scale_mm = 2.0;
  // Step 1 also solves broad offsets along the normal (offset_basis.hpp) for what the identity
  // modes cannot hold, each bump's amplitude under a prior of this sd (mm; 0 = off): an
  // out-of-span face's bumps then bend the surface instead of sliding the modes' vertices
  // along it.
  double offset_amplitude_mm = 0.5;
  OffsetBasisOptions offsets;
  bool refine = true;  // run step 2
  RefineOptions refine_options;
};

// How strongly each part of a guide recipe was made (expression_amplitude.hpp).
struct AmplitudeOptions {
  int iterations = 6;
  double max_distance_mm = 10.0;  // a transferred chin can start this far from the depth
  double max_normal_angle_deg = 70;
  double robust_scale_mm = 3.0;  // Cauchy scale of the depth residual
  double w_fea = 0.1;            // a landmark's weight against one depth sample's
  double landmark_huber_mm = 3.0;
  // Against a part's amplitude moving from 1, in mm^2 per unit^2: a part the depth hardly sees
  // (a 0.2 eye squint) stays as the recipe says; a jaw seen by a thousand samples follows them.
  double prior = 100.0;
  double min_amplitude = 0.0;
  double max_amplitude = 2.0;
  double moving_mm = 0.2;  // vertices every part moves less than this take no part
};

// Where an expression fit starts from the subject's neutral S0 and the guide's G0 -> Gi:
//  kModelShapes: S0 + (Gi - G0), the face model's own expression shapes added to the neutral,
//    as the model composes any identity with any expression;
//  kDeformationTransfer: Gi's deformation gradients carried onto S0 (FaceWarehouse 3.2.2),
//    which scales the motion by the subject's proportions.
// Choosing between the two by the capture's depth and landmark energy picked the wrong one in
// the realistic world (docs/tuning.md), so the choice is an option.
enum class ExpressionStart { kModelShapes, kDeformationTransfer };

struct ExpressionFitOptions {
  ExpressionStart start = ExpressionStart::kModelShapes;
  // Point-to-plane ICP on the rigid vertices + landmarks: steps with a gate shrinking from 15 to
  // 4 mm, then up to 40 more at 4 mm until the pose settles (align_rigid).
  int rigid_iterations = 8;
  // Scale each recipe part to the capture before refining (needs the guide's parts).
  bool scale_parts = true;
  AmplitudeOptions amplitude_options;
  bool refine = true;
  RefineOptions refine_options;
};

struct FitTimes {
  double initial_ms = 0;  // step 1 (neutral) or transfer + rigid (expression)
  double refine_ms = 0;
  double total_ms() const { return initial_ms + refine_ms; }
};

struct FitResult {
  // Final mesh (refined when refinement ran), model frame, 3 * vertex_count floats, mm.
  std::vector<float> vertices;
  // Before refinement: the PCA fit (neutral) or the scaled, aligned start (expressions).
  std::vector<float> initial_vertices;
  RigidPose camera_from_model;
  std::vector<float> identity_coeffs;  // sigma units (neutral fits; empty for expressions)
  // Expressions: how strongly each part of the guide recipe was made (1 = as the recipe);
  // empty without parts.
  std::vector<double> part_amplitudes;
  int rounds = 0;  // least-squares rounds of the PCA step (neutral fits)
  // Per-vertex point-to-plane distance to the depth map, mm (signed: + in front of the
  // surface); NaN where the vertex has no valid correspondence. For the final and the
  // initial mesh.
  std::vector<float> vertex_residual_mm;
  std::vector<float> initial_vertex_residual_mm;
  // Over face vertices with a correspondence; a fit whose final mesh has none fails instead
  // (what to do, not "RMS nan"). The initial one is NaN when the start mesh had none.
  double rms_to_depth_mm = 0;
  double rms_to_depth_mm_initial = 0;
  int depth_correspondences = 0;
  // Landmark residuals of the final mesh: 3D distance (interior) or ray distance (contour), mm.
  std::array<double, kFitLandmarkCount> landmark_residual_mm{};
  std::array<int, kFitLandmarkCount> landmark_vertex{};  // mesh vertex used (contour slides)
  FitTimes times;

  // Camera-frame position of vertex i.
  Eigen::Vector3d camera_vertex(int i) const;
};

// Neutral fit (steps 1 and 2). `initial` (optional) starts from a previous fit's pose and
// identity, as a refit after operator corrections does. `model_system` (optional, see
// model_refine_system()) is a refinement matrix shared by every neutral fit with this model;
// without it the fit factorizes its own from its step-1 mesh.
Result<FitResult> fit_neutral(const FaceModel& model, const FitTarget& target,
                              const NeutralFitOptions& options = {},
                              const FitResult* initial = nullptr,
                              const RefineSystem* model_system = nullptr);

// The matrix part of the refinement weights (what a RefineSystem is built with).
RefineSystemOptions refine_system_options(const RefineOptions& options);

// The refinement matrix of the model's mean face (refine_system.hpp), built once per model so
// that a neutral fit costs back-substitutions, not a factorization (~110 ms here).
Result<RefineSystem> model_refine_system(const FaceModel& model, const RefineOptions& options = {});

// Step 2 alone: refines `start` (model frame, with `camera_from_model`) against the target.
// The result's initial_* fields describe `start`.
// `system` (optional) is a subject's shared normal matrix (see refine_system.hpp); it is used
// when its weights are the options' ones, otherwise the fit factorizes its own.
Result<FitResult> refine_fit(const FaceModel& model, const FitTarget& target,
                             std::span<const float> start, const RigidPose& camera_from_model,
                             const RefineOptions& options = {},
                             const RefineSystem* system = nullptr);

// Rigid pose of a fixed-shape mesh (model frame) against the target: Procrustes on the
// interior landmarks, then point-to-plane ICP on the model's rigid vertices above the chin (the
// neck is neither fitted by the neutral nor still when the jaw opens). `second_start`
// (optional, without `initial`): the ICP also runs from a Procrustes on these landmarks alone,
// and the pose that fits the rigid vertices' depth better is kept. `still_vertices`
// (optional) replace the model's rigid subset in the ICP: that subset is mostly the back of the
// head and the ears, which a frontal capture's depth hardly shows, so without them the pose is
// the landmarks' alone.
Result<RigidPose> align_rigid(const FaceModel& model, const FitTarget& target,
                              std::span<const float> mesh, int iterations,
                              const std::optional<RigidPose>& initial = std::nullopt,
                              std::span<const int> second_start = {},
                              std::span<const std::uint32_t> still_vertices = {});

// The landmarks an expression moves least: the nose (27-35) and the eyes (36-47). An
// expression's start from all of them fell into the wrong ICP basin on open mouths, whose
// lip and jaw points (and dlib's convention there) move with the expression.
inline constexpr std::array<int, 21> kRigidFaceLandmarks = {
    27, 28, 29, 30, 31, 32, 33, 34, 35, 36, 37, 38, 39, 40, 41, 42, 43, 44, 45, 46, 47};

// An operator's correction: landmark `index` moved to `pixel` (depth image). Interior points
// are re-lifted with the target's depth.
struct LandmarkCorrection {
  int index = 0;
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();
  bool remove = false;  // drop the point instead of moving it
};

// Applies corrections to a target (errors on a bad index).
Result<void> apply_corrections(FitTarget& target, std::span<const LandmarkCorrection> corrections);

// Metrics helpers for evaluation: mean distance between two meshes (camera frames) over a
// vertex subset, and RMS of a residual vector over a subset (NaNs skipped).
double mean_vertex_distance(std::span<const float> a, const RigidPose& pose_a,
                            std::span<const float> b, const RigidPose& pose_b,
                            std::span<const std::uint32_t> subset);

}  // namespace fb
