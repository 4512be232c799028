#include <chrono>
#include <vector>

#include "algo/core/clock.hpp"
#include "algo/fitting/expression_amplitude.hpp"
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

// The expression's start on the subject (ExpressionStart).
Result<std::vector<float>> start_mesh(const ExpressionTransfer& transfer,
                                      std::span<const float> guide_expression,
                                      ExpressionStart start) {
  if (start == ExpressionStart::kDeformationTransfer) return transfer.transfer(guide_expression);
  const std::span<const float> s0 = transfer.neutral(), g0 = transfer.guide_neutral();
  if (guide_expression.size() != s0.size())
    return fail("expression fit: the guide expression has the wrong vertex count");
  std::vector<float> out(s0.size());
  for (std::size_t i = 0; i < out.size(); ++i) out[i] = s0[i] + (guide_expression[i] - g0[i]);
  return out;
}

// The parts' displacements on the subject. Model shapes: each part less G0. Transfer: the
// transfer of G0 plus each part, less the transfer of G0 itself (the transfer is nearly linear
// in the guide; its fourth vertices are not).
Result<std::vector<std::vector<float>>> part_displacements(
    const ExpressionTransfer& transfer, std::span<const std::vector<float>> guide_parts,
    ExpressionStart start) {
  const bool model_shapes = start == ExpressionStart::kModelShapes;
  const std::span<const float> rest =
      model_shapes ? transfer.guide_neutral() : transfer.rest_transfer();
  std::vector<std::vector<float>> out;
  for (const auto& part : guide_parts) {
    if (part.size() != rest.size())
      return fail("expression fit: a guide part has the wrong vertex count");
    std::vector<float> moved = part;
    if (!model_shapes) {
      auto t = transfer.transfer(part);
      if (!t) return t.failure();
      moved = std::move(*t);
    }
    for (std::size_t i = 0; i < moved.size(); ++i) moved[i] -= rest[i];
    out.push_back(std::move(moved));
  }
  return out;
}

}  // namespace

Result<FitResult> fit_expression(const FaceModel& model, const ExpressionTransfer& transfer,
                                 std::span<const float> guide_expression, const FitTarget& target,
                                 const ExpressionFitOptions& options,
                                 const std::optional<RigidPose>& initial_pose,
                                 std::span<const std::vector<float>> guide_parts) {
  const auto t0 = Clock::now();
  auto start = start_mesh(transfer, guide_expression, options.start);
  if (!start) return start.failure();
  const std::vector<std::uint32_t> still =
      still_vertices(model, transfer.guide_neutral(), guide_expression);
  auto pose = align_rigid(model, target, *start, options.rigid_iterations, initial_pose,
                          kRigidFaceLandmarks, still);
  if (!pose) return pose.failure();
  std::vector<double> amplitudes;
  if (options.scale_parts && !guide_parts.empty()) {
    auto parts = part_displacements(transfer, guide_parts, options.start);
    if (!parts) return parts.failure();
    auto a = fit_amplitudes(model, target, *start, *pose, *parts, options.amplitude_options);
    if (!a) return a.failure();
    amplitudes = std::move(*a);
    for (std::size_t k = 0; k < parts->size(); ++k)
      for (std::size_t i = 0; i < start->size(); ++i)
        (*start)[i] += static_cast<float>(amplitudes[k] - 1.0) * (*parts)[k][i];
  }
  const double initial_ms = ms_since(t0);
  RefineOptions refine = options.refine_options;
  if (!options.refine) refine.iterations = 0;
  auto result = refine_fit(model, target, *start, *pose, refine, &transfer.refine_system());
  if (!result) return result.failure();
  result->times.initial_ms = initial_ms;
  result->part_amplitudes = std::move(amplitudes);
  return result;
}

}  // namespace fb
