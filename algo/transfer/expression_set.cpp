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

namespace {

// kTargetTents: the source's Q blended at the target's vertices, solved on the target's tents.
Result<void> solve_on_target_tents(const VtcSource& source, const TentTopology& target_topology,
                                   const Points& target_aligned, const Correspondence& corr,
                                   std::span<const Points> source_expressions,
                                   CrossTopologyTransfer& out) {
  auto target = VtcTarget::create(target_topology, target_aligned);
  if (!target) return target.failure();
  out.factor_ms = target->factor_ms();
  const auto t0 = Clock::now();
  for (const Points& expression : source_expressions) {
    auto q = source.transformations(expression);
    if (!q) return q.failure();
    auto moved = target->solve(map_transformations(corr, *q),
                               map_points(corr, expression - source.neutral()));
    if (!moved) return moved.failure();
    out.expressions.push_back(out.alignment.inverse(*moved));
  }
  if (!source_expressions.empty())
    out.per_expression_ms = ms_since(t0) / static_cast<double>(source_expressions.size());
  return success();
}

// The source's vertices on the aligned target surface (the inverse correspondence). Where the
// target does not reach (unmatched, or several source vertices clamped onto one point of the
// target's border, which leaves zero-length edges and a singular system) the offset from the
// source neutral is filled in from the neighbours' (Jacobi iterations of the ring mean).
Points resample(const VtcSource& source, const Points& target_aligned, const Correspondence& back) {
  const TentTopology& topo = source.topology();
  const Points& s = source.neutral();
  Points offset = map_points(back, target_aligned) - s;
  std::vector<bool> fill(back.points.size(), false);
  for (int v = 0; v < topo.vertex_count; ++v) {
    const auto vi = static_cast<std::size_t>(v);
    fill[vi] = fill[vi] || !back.points[vi].matched;
    for (std::uint32_t u : topo.ring(v)) {
      const double was = (s.row(v) - s.row(u)).norm();
      const double now = (s.row(v) + offset.row(v) - s.row(u) - offset.row(u)).norm();
      if (now < 0.05 * was) fill[vi] = fill[u] = true;
    }
  }
  constexpr int kFillIterations = 300;
  for (int it = 0; it < kFillIterations; ++it)
    for (int v = 0; v < topo.vertex_count; ++v) {
      const auto ring = topo.ring(v);
      if (!fill[static_cast<std::size_t>(v)] || ring.empty()) continue;
      Eigen::RowVector3d sum = Eigen::RowVector3d::Zero();
      for (std::uint32_t u : ring) sum += offset.row(u);
      offset.row(v) = sum / static_cast<double>(ring.size());
    }
  return s + offset;
}

// kResample: the target resampled at the source's vertices (the inverse correspondence: each
// source vertex's point on the aligned target), solved there on the source's tents, the
// displacement carried back to the target's vertices through their source points. A source
// vertex the target does not cover keeps its own neutral position (it moves as the source).
Result<void> solve_resampled(const VtcSource& source, const TentTopology& target_topology,
                             const Points& target_aligned, const Points& target_features_aligned,
                             const Points& source_features, const Correspondence& corr,
                             std::span<const Points> source_expressions,
                             CrossTopologyTransfer& out) {
  const auto t0 = Clock::now();
  auto back = find_correspondence(target_aligned, fan_triangles(target_topology.faces),
                                  target_features_aligned, source.neutral(), source_features);
  if (!back) return back.failure();
  const Points resampled = resample(source, target_aligned, *back);
  out.correspondence_ms += ms_since(t0);
  auto target = VtcTarget::create(source.topology(), resampled);
  if (!target) return target.failure();
  out.factor_ms = target->factor_ms();
  const auto t1 = Clock::now();
  for (const Points& expression : source_expressions) {
    auto moved = vtc_transfer(source, *target, expression);
    if (!moved) return moved.failure();
    const Points moved_target = target_aligned + map_points(corr, *moved - resampled);
    out.expressions.push_back(out.alignment.inverse(moved_target));
  }
  if (!source_expressions.empty())
    out.per_expression_ms = ms_since(t1) / static_cast<double>(source_expressions.size());
  return success();
}

}  // namespace

Result<CrossTopologyTransfer> transfer_expression_set_across(
    const TentTopology& source_topology, const Points& source_neutral,
    std::span<const Points> source_expressions, const Points& source_features,
    const TentTopology& target_topology, const Points& target_neutral,
    const Points& target_features, CrossTopologyMethod method) {
  CrossTopologyTransfer out;
  const auto t0 = Clock::now();
  auto corr = find_correspondence(source_neutral, fan_triangles(source_topology.faces),
                                  source_features, target_neutral, target_features);
  if (!corr) return corr.failure();
  out.correspondence_ms = ms_since(t0);
  out.unmatched = corr->unmatched;
  out.alignment = corr->alignment;
  auto source = VtcSource::create(source_topology, source_neutral);
  if (!source) return source.failure();
  const Points target_aligned = out.alignment.apply(target_neutral);
  Result<void> ok = method == CrossTopologyMethod::kResample
                        ? solve_resampled(*source, target_topology, target_aligned,
                                          out.alignment.apply(target_features), source_features,
                                          *corr, source_expressions, out)
                        : solve_on_target_tents(*source, target_topology, target_aligned, *corr,
                                                source_expressions, out);
  if (!ok) return ok.failure();
  return out;
}

}  // namespace fb
