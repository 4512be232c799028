#include "algo/transfer/expression_set.hpp"

#include "algo/core/clock.hpp"

namespace fb {

Result<ExpressionSetTransfer> transfer_expression_set(const TentTopology& topology,
                                                      const Points& source_neutral,
                                                      std::span<const Points> source_expressions,
                                                      const Points& target_neutral,
                                                      bool align_target) {
  ExpressionSetTransfer out;
  if (align_target) {
    if (target_neutral.rows() != source_neutral.rows())
      return fail("VTC: the target has " + std::to_string(target_neutral.rows()) +
                  " vertices, the source " + std::to_string(source_neutral.rows()));
    auto align = align_similarity(target_neutral, source_neutral);
    if (!align) return align.failure();
    out.alignment = *align;
  }
  auto source = VtcSource::create(topology, source_neutral);
  if (!source) return source.failure();
  auto target = VtcTarget::create(topology, out.alignment.apply(target_neutral));
  if (!target) return target.failure();
  out.factor_ms = target->factor_ms();
  const auto t0 = Clock::now();
  for (const Points& expression : source_expressions) {
    auto moved = vtc_transfer(*source, *target, expression);
    if (!moved) return moved.failure();
    out.expressions.push_back(out.alignment.inverse(*moved));
  }
  if (!source_expressions.empty())
    out.per_expression_ms = ms_since(t0) / static_cast<double>(source_expressions.size());
  return out;
}

Result<CrossTopologyTransfer> transfer_expression_set_across(
    const TentTopology& source_topology, const Points& source_neutral,
    std::span<const Points> source_expressions, const Points& source_features,
    const TentTopology& target_topology, const Points& target_neutral,
    const Points& target_features) {
  CrossTopologyTransfer out;
  auto t0 = Clock::now();
  auto corr = find_correspondence(source_neutral, fan_triangles(source_topology.faces),
                                  source_features, target_neutral, target_features);
  if (!corr) return corr.failure();
  out.correspondence_ms = ms_since(t0);
  out.unmatched = corr->unmatched;
  out.alignment = corr->alignment;
  auto source = VtcSource::create(source_topology, source_neutral);
  if (!source) return source.failure();
  auto target = VtcTarget::create(target_topology, out.alignment.apply(target_neutral));
  if (!target) return target.failure();
  out.factor_ms = target->factor_ms();
  t0 = Clock::now();
  for (const Points& expression : source_expressions) {
    auto q = source->transformations(expression);
    if (!q) return q.failure();
    auto moved = target->solve(map_transformations(*corr, *q),
                               map_points(*corr, expression - source_neutral));
    if (!moved) return moved.failure();
    out.expressions.push_back(out.alignment.inverse(*moved));
  }
  if (!source_expressions.empty())
    out.per_expression_ms = ms_since(t0) / static_cast<double>(source_expressions.size());
  return out;
}

}  // namespace fb
