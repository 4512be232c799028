// Example-based facial rigging (Li, Weise and Pauly 2010; FaceWarehouse section 3.2.3): from a
// subject's example meshes S_0 (neutral) .. S_m with known blendshape weights alpha_i, and a
// generic rig A_0 .. A_n (same topology), compute the subject's personal blendshapes
// B_0 = S_0, B_1 .. B_n.
//
// Deformation-gradient space, per triangle t. A frame is F = [v2 - v1, v3 - v1, n / sqrt|n|].
// Only the two edge columns of the personal frames are linear in the vertices, and the energy
// below is separable per column, so the unknowns are the edge deltas X_j^t = E(B_j^t) - E(B_0^t)
// (3 x 2 each, E = the first two frame columns):
//
//   E_t = sum_i | sum_j alpha_ij X_j^t - (E(S_i^t) - E(S_0^t)) |^2             (examples)
//       + beta sum_j w_j^t | X_j^t - (G_j^t G_0^t^-1 - I) E(S_0^t) |^2        (generic prior)
//
// with G the generic frames, so the prior asks B_j B_0^-1 to match A_j A_0^-1 (the generic
// rig's relative deformation), and Li et al.'s weight
//   w_j^t = ((1 + |G_j^t G_0^t^-1 - I|_F) / (kappa + |G_j^t G_0^t^-1 - I|_F))^theta
// which holds triangles the generic shape j leaves still (w -> 1/kappa^theta) more firmly than
// those it moves (w -> 1). Each triangle is one (n x n) SPD solve with 6 right-hand sides.
//
// Vertices: every shape's delta d_j minimises sum_t |K_t d_j - X_j^t|^2 over the three edges of
// each triangle (a Poisson-style problem) plus eps |d_j - (A_j - A_0)|^2, which only fixes the
// translation (eps is tiny). The sparse matrix K^T K + eps I is the same for all shapes: it is
// factorised once and each round is one multi-column back-substitution.
//
// Weights: with the blendshapes fixed, each example's alpha_i is re-estimated by bounded least
// squares in [0, 1]^n, regularised towards the known (guide) weights:
//   min_a |sum_j a_j (B_j - B_0) - (S_i - S_0)|^2 / N + gamma |a - alpha_i^guide|^2.
// The two steps alternate for `rounds` rounds.
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <string_view>
#include <vector>

#include "algo/core/result.hpp"

namespace fb {

struct RigOptions {
  int rounds = 3;  // blendshape solve + weight update alternations
  // beta. Fitted example meshes carry their fitting error (eval rig, 5 subjects, --truth
  // transfer: expression parts 0.47 mm off against a 0.32 mm personal signal), so the prior
  // earns weight: held-out 0.73 mm at 0.05, 0.69 mm at 0.2 (baseline 0.80 mm); train 0.22 ->
  // 0.32 mm; with exact examples 0.233 -> 0.237 mm.
  double prior_weight = 0.2;
  double kappa = 0.1;  // Li et al.'s weight parameters
  double theta = 2.0;
  // gamma (mm^2 per unit weight^2); the data term is a mean over vertices, so this is "how many
  // mm^2 of mean squared misfit one unit of weight change must buy".
  double weight_regularization = 0.05;
  bool update_weights = true;
  int weight_vertex_stride = 3;  // every k-th weight vertex enters the weight update
  // Vertices used for the weight update (e.g. the face region); empty = all.
  std::vector<std::uint32_t> weight_vertices;
  double anchor_weight = 1e-6;  // eps of the vertex solve (fixes the translation only)
  int threads = 2;
  // Called with a stage name and the fraction done (0..1) of the whole job.
  std::function<void(std::string_view stage, double fraction)> progress;
};

struct RigInput {
  std::span<const std::uint32_t> triangles;            // 3 * T, shared by every mesh
  std::span<const float> generic_neutral;              // A_0, 3 * V floats
  std::vector<std::span<const float>> generic_shapes;  // A_1 .. A_n (full shapes, not deltas)
  std::vector<std::span<const float>> examples;        // S_0 (neutral) .. S_m
  std::vector<std::vector<float>> example_weights;     // m + 1 rows of n weights (row 0 unused)
};

struct RigResult {
  std::vector<float> neutral;               // B_0 = S_0
  std::vector<std::vector<float>> shapes;   // B_1 .. B_n, full shapes
  std::vector<std::vector<float>> weights;  // re-estimated alpha_i (row 0 all zero)
  // Per example and vertex: |B_0 + sum_j alpha_ij (B_j - B_0) - S_i| in mm (final weights).
  std::vector<std::vector<float>> vertex_residual_mm;
  std::vector<double> example_residual_mm;  // mean of the above over all vertices, per example
  std::vector<double> round_residual_mm;    // mean example residual after each round
  double seconds = 0;
};

// Evaluates a rig: B_0 + sum_j w_j (B_j - B_0) (3 * V floats).
std::vector<float> evaluate_rig(std::span<const float> neutral,
                                const std::vector<std::vector<float>>& shapes,
                                std::span<const float> weights);

// Errors: empty or mismatched meshes, weights of the wrong length or outside [0, 1], no
// example besides the neutral, degenerate triangles in the neutral example.
Result<RigResult> rig_subject(const RigInput& input, const RigOptions& options = {});

}  // namespace fb
