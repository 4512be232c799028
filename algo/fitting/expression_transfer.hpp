// Deformation transfer (Sumner and Popovic 2004) of a guide deformation G0 -> Gi onto a
// subject's fitted neutral S0 (FaceWarehouse 3.2.2). All meshes share the model topology, so the
// triangle correspondence is the identity.
//
// Per triangle, with V = [v2 - v1, v3 - v1, v4 - v1] and v4 = v1 + n / sqrt|n| (n the
// unnormalised normal): source gradient Q = V_i V_0^-1; the target's vertices (and one free
// fourth vertex per triangle) minimise sum_t |X_t W_t^-1 - Q_t|_F^2, W_t the fitted neutral's
// V. The normal matrix depends only on S0: it is factorised once in create() and each
// transfer is three back-substitutions.
#pragma once

#include <memory>
#include <span>
#include <vector>

#include "algo/core/result.hpp"
#include "algo/facemodel/face_model.hpp"
#include "algo/fitting/face_fit.hpp"

namespace fb {

class ExpressionTransfer {
 public:
  // `neutral_fit` is S0 and `guide_neutral` G0 (3 * vertex_count floats each, model frame).
  // Also factorizes the subject's refinement matrix (refine_system.hpp) from S0 with the
  // weights of `refine`, which every fit_expression() of this subject then shares.
  static Result<ExpressionTransfer> create(const FaceModel& model,
                                           std::span<const float> neutral_fit,
                                           std::span<const float> guide_neutral,
                                           const RefineOptions& refine = {});
  ExpressionTransfer(ExpressionTransfer&&) noexcept;
  ExpressionTransfer& operator=(ExpressionTransfer&&) noexcept;
  ~ExpressionTransfer();

  // S_i: the fitted neutral deformed like G0 -> `guide_expression`.
  Result<std::vector<float>> transfer(std::span<const float> guide_expression) const;

  const RefineSystem& refine_system() const;
  std::span<const float> guide_neutral() const;  // G0
  std::span<const float> neutral() const;        // S0
  // transfer(G0): the fitted neutral as the transfer reproduces it; a guide part's displacement
  // on the subject is its transfer minus this.
  std::span<const float> rest_transfer() const;
  // Both factorizations of create(): the transfer's and the refinement's.
  double factorization_ms() const;

 private:
  struct State;
  explicit ExpressionTransfer(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;
};

// Expression fit (3.2.2): start from the neutral moved as G0 -> Gi (options.start: the face
// model's own shapes added, or the deformation transferred), align it rigidly to this capture
// (landmarks + ICP on the vertices the expression leaves still), scale each part of the guide's
// recipe to the capture (expression_amplitude.hpp), then refine with E2 and this capture's
// landmarks.
// `guide_parts` are G0 plus one recipe part each (algo/guide's guide_part_meshes); without them
// the start is refined as it is. `initial_pose` (e.g. the neutral's pose) seeds the alignment.
Result<FitResult> fit_expression(const FaceModel& model, const ExpressionTransfer& transfer,
                                 std::span<const float> guide_expression, const FitTarget& target,
                                 const ExpressionFitOptions& options = {},
                                 const std::optional<RigidPose>& initial_pose = std::nullopt,
                                 std::span<const std::vector<float>> guide_parts = {});

}  // namespace fb
