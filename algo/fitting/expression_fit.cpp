#include <chrono>
#include <vector>

#include "algo/core/clock.hpp"
#include "algo/fitting/expression_transfer.hpp"

namespace fb {
namespace {

// The face's fitting vertices this guide expression moves by less than 0.5 mm (mouth_stretch:
// the forehead, nose and eyes). Fewer than 200: the model's rigid subset (an empty list).
std::vector<std::uint32_t> still_vertices(const FaceModel& model, std::span<const float> g0,
                                          std::span<const float> gi) {
  std::vector<std::uint32_t> out;
  if (g0.size() != gi.size()) return out;
  for (std::uint32_t v : model.fitting_vertices) {
    const std::size_t i = 3 * std::size_t{v};
    if (i + 2 >= gi.size()) continue;
    const float dx = gi[i] - g0[i], dy = gi[i + 1] - g0[i + 1], dz = gi[i + 2] - g0[i + 2];
    if (dx * dx + dy * dy + dz * dz < 0.25f) out.push_back(v);
  }
  if (out.size() < 200) out.clear();
  return out;
}

}  // namespace

Result<FitResult> fit_expression(const FaceModel& model, const ExpressionTransfer& transfer,
                                 std::span<const float> guide_expression, const FitTarget& target,
                                 const ExpressionFitOptions& options,
                                 const std::optional<RigidPose>& initial_pose) {
  const auto t0 = Clock::now();
  auto start = transfer.transfer(guide_expression);
  if (!start) return start.failure();
  const std::vector<std::uint32_t> still =
      still_vertices(model, transfer.guide_neutral(), guide_expression);
  auto pose = align_rigid(model, target, *start, options.rigid_iterations, initial_pose,
                          kRigidFaceLandmarks, still);
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
