// VTC-based deformation transfer (Song et al., section IV, eq. 1-7). The source side turns each
// source expression into one 3x3 transformation Q per vertex (eq. 2: source neutral tent ->
// source expression tent). The target side finds the target expression whose tents deform by
// those Q in the least-squares sense, the consistency constraint (eq. 3) holding by
// construction because neighbouring tents share their vertices' positions. The unknowns are
// the target's vertices and one apex per vertex (as Sumner and Popovic's fourth vertex); the
// normal matrix A^T A depends on the target neutral only, so it is factored once
// (VtcTarget::create) and each expression costs one back-substitution with three right-hand
// sides (x, y, z).
#pragma once

#include <memory>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "algo/core/result.hpp"
#include "algo/transfer/tent_mesh.hpp"

namespace fb {

using Transformations = std::vector<Eigen::Matrix3d>;

class VtcSource {
 public:
  // `neutral`: the source neutral, one row per vertex of `topology`.
  static Result<VtcSource> create(TentTopology topology, const Points& neutral);

  // Q per vertex (eq. 2) of the source neutral -> `expression` (same vertex count).
  Result<Transformations> transformations(const Points& expression) const;

  const TentTopology& topology() const { return topology_; }
  const Points& neutral() const { return neutral_; }

 private:
  VtcSource() = default;
  TentTopology topology_;
  Points neutral_;
  std::vector<Eigen::MatrixX3d> inverses_;  // w^T (w w^T)^-1 of the neutral's tents
};

class VtcTarget {
 public:
  static Result<VtcTarget> create(TentTopology topology, const Points& neutral);
  VtcTarget(VtcTarget&&) noexcept;
  VtcTarget& operator=(VtcTarget&&) noexcept;
  ~VtcTarget();

  // The target expression whose tents deform by `q` (one per target vertex). The tents fix the
  // shape up to one translation per connected component: it is chosen so that the quarter of
  // the component's vertices with the smallest `motion` (the source's displacement brought to
  // the target's vertices) move as `motion` says there, i.e. what the source holds still stays.
  Result<Points> solve(std::span<const Eigen::Matrix3d> q, const Points& motion) const;

  const TentTopology& topology() const;
  const Points& neutral() const;
  double factor_ms() const;           // building and factoring A^T A
  long long factor_nonzeros() const;  // of the Cholesky factor L

 private:
  struct State;
  explicit VtcTarget(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;
};

// Source and target of one topology (the identity correspondence): the target expression for
// `source_expression`.
Result<Points> vtc_transfer(const VtcSource& source, const VtcTarget& target,
                            const Points& source_expression);

}  // namespace fb
