#include <chrono>

#include "algo/core/clock.hpp"
#include "algo/fitting/expression_transfer.hpp"

namespace fb {

Result<FitResult> fit_expression(const FaceModel& model, const ExpressionTransfer& transfer,
                                 std::span<const float> guide_expression, const FitTarget& target,
                                 const ExpressionFitOptions& options,
                                 const std::optional<RigidPose>& initial_pose) {
  const auto t0 = Clock::now();
  auto start = transfer.transfer(guide_expression);
  if (!start) return start.failure();
  auto pose = align_rigid(model, target, *start, options.rigid_iterations, initial_pose);
  if (!pose) return pose.failure();
  const double initial_ms = ms_since(t0);
  RefineOptions refine = options.refine_options;
  if (!options.refine) refine.iterations = 0;
  auto result = refine_fit(model, target, *start, *pose, refine, &transfer.refine_system());
  if (!result) return result.failure();
  result->times.initial_ms = initial_ms;
  return result;
}

}  // namespace fb
