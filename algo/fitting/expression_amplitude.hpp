// How strongly this person made each part of a guide expression. The guide's recipe is a sum of
// model shapes at fixed weights (mouth_stretch: jawOpen 0.7, mouthStretch 0.4, ...), and the
// expression fit's start opens the jaw as far as the recipe says. People do not: one opens the
// mouth half as far, another further. Before the Laplacian refinement (which keeps the start's
// shape and only follows depth within its gate), the expression fit scales each part of its
// start to the capture's depth and landmarks:
//
//   x(a) = S + sum_k (a_k - 1) D_k,   E(a) = sum_v rho(n_v . (R x_v + t - q_v))^2
//                                           + w_fea sum_l |landmark residual|^2
//                                           + prior sum_k (a_k - 1)^2,
//
// S the start (ExpressionStart), D_k recipe part k's displacement on the subject, a_k in
// [min, max] (1 = as the recipe), rho a Cauchy weight, Gauss-Newton with the correspondences
// re-found every step. The pose is the expression's rigid alignment (on the vertices the
// expression leaves still), so only the moving vertices take part.
#pragma once

#include <span>
#include <vector>

#include "algo/core/result.hpp"
#include "algo/facemodel/face_model.hpp"
#include "algo/fitting/face_fit.hpp"

namespace fb {

// The amplitudes a_k (one per part, 1 = as the recipe) of `parts` (D_k: 3 * vertex_count floats
// each, model frame) around `start` (S, model frame, posed by `camera_from_model`).
Result<std::vector<double>> fit_amplitudes(const FaceModel& model, const FitTarget& target,
                                           std::span<const float> start,
                                           const RigidPose& camera_from_model,
                                           std::span<const std::vector<float>> parts,
                                           const AmplitudeOptions& options = {});

}  // namespace fb
