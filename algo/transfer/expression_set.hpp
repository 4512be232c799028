// A whole expression set moved from a source face onto a target neutral of the same topology:
// the target aligned to the source (alignment.hpp), factored once, one solve per expression,
// the results moved back into the target's frame. `facebooth transfer` and the lab's eval
// transfer both run this.
#pragma once

#include <span>
#include <vector>

#include "algo/core/result.hpp"
#include "algo/transfer/alignment.hpp"
#include "algo/transfer/correspondence.hpp"
#include "algo/transfer/vtc_transfer.hpp"

namespace fb {

struct ExpressionSetTransfer {
  std::vector<Points> expressions;  // the target's, in the target's frame
  Similarity alignment;             // target -> source frame
  double factor_ms = 0;             // VtcTarget::create
  double per_expression_ms = 0;     // mean of source Q + solve + moving back
};

// `align_target`: false when both are already in one frame (e.g. fits of the same model).
Result<ExpressionSetTransfer> transfer_expression_set(const TentTopology& topology,
                                                      const Points& source_neutral,
                                                      std::span<const Points> source_expressions,
                                                      const Points& target_neutral,
                                                      bool align_target = true);

struct CrossTopologyTransfer : ExpressionSetTransfer {
  double correspondence_ms = 0;  // find_correspondence
  int unmatched = 0;             // target vertices without a source point
};

// How the solve between topologies runs (docs/transfer.md, "Between topologies").
enum class CrossTopologyMethod {
  // Section V as the paper does it: the target resampled at the source's vertices (each source
  // vertex's point on the target surface), the VTC solve on the source's own tents there, and
  // the resampled mesh's displacement carried back to every target vertex through its source
  // point. The solve never sees the target's tents, so it works the same on any triangulation.
  kResample,
  // The source's per-vertex transformations blended at each target vertex's source point and
  // the VTC solve on the target's own tents (the first version; weak on meshes whose vertices
  // sit in the plane of their ring, e.g. triangles split at their centroids).
  kTargetTents,
};

// Source and target of different topology (section V, correspondence.hpp), in the source's
// frame (aligned by the feature points), moved back to the target's.
// `*_features`: corresponding 3D points on each neutral (e.g. the 68 landmarks).
Result<CrossTopologyTransfer> transfer_expression_set_across(
    const TentTopology& source_topology, const Points& source_neutral,
    std::span<const Points> source_expressions, const Points& source_features,
    const TentTopology& target_topology, const Points& target_neutral,
    const Points& target_features, CrossTopologyMethod method = CrossTopologyMethod::kResample);

}  // namespace fb
