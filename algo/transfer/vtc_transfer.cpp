#include "algo/transfer/vtc_transfer.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include <Eigen/SparseCholesky>

#include "algo/core/clock.hpp"

namespace fb {

namespace {

Result<void> check_points(const TentTopology& topology, const Points& points, const char* what) {
  if (points.rows() != topology.vertex_count)
    return fail(std::string(what) + " has " + std::to_string(points.rows()) +
                " vertices, its topology " + std::to_string(topology.vertex_count));
  if (!points.allFinite()) return fail(std::string(what) + " has non-finite coordinates");
  return success();
}

std::vector<Eigen::MatrixX3d> tent_inverses(const TentTopology& topology, const Points& points) {
  const Points apexes = tent_apexes(topology, points);
  std::vector<Eigen::MatrixX3d> out(static_cast<std::size_t>(topology.vertex_count));
  for (int v = 0; v < topology.vertex_count; ++v)
    out[static_cast<std::size_t>(v)] = tent_inverse(tent_coordinates(topology, points, apexes, v));
  return out;
}

// Row weights: the square root of each vertex's area over the mean, so the least squares sums
// the tents' mismatch over the surface rather than over the vertices. (The paper weights every
// vertex alike; on the face model's uneven mesh area weights lower the cross-subject error by
// about a tenth, docs/transfer.md; a self-transfer stays exact either way.)
std::vector<double> row_weights(const TentTopology& topology, const Points& neutral) {
  std::vector<double> w = vertex_areas(topology.faces, neutral);
  double mean = 0;
  for (double a : w) mean += a;
  mean = std::max(mean / static_cast<double>(std::max<std::size_t>(w.size(), 1)), 1e-300);
  for (double& a : w) a = std::sqrt(std::max(a, 1e-12 * mean) / mean);
  return w;
}

// A^T of eq. 5-6: row (3v + k) of A maps the unknowns (vertices 0..N-1, apexes N..2N-1) to
// column k of the target tent's Q = w' M, M = w^T (w w^T)^-1 of the target neutral, times the
// vertex's row weight.
Eigen::SparseMatrix<double> tent_system_transposed(const TentTopology& topology,
                                                   const std::vector<Eigen::MatrixX3d>& inverses,
                                                   const std::vector<double>& weights) {
  const int n = topology.vertex_count;
  std::vector<Eigen::Triplet<double>> trip;
  trip.reserve(topology.rings.size() * 3 + static_cast<std::size_t>(n) * 6);
  for (int v = 0; v < n; ++v) {
    const auto ring = topology.ring(v);
    if (ring.empty()) continue;
    const Eigen::MatrixX3d mv =
        inverses[static_cast<std::size_t>(v)] * weights[static_cast<std::size_t>(v)];
    for (int k = 0; k < 3; ++k) {
      const int row = 3 * v + k;
      for (std::size_t j = 0; j < ring.size(); ++j)
        trip.emplace_back(int(ring[j]), row, mv(static_cast<Eigen::Index>(j), k));
      trip.emplace_back(n + v, row, mv(mv.rows() - 1, k));
      trip.emplace_back(v, row, -mv.col(k).sum());
    }
  }
  Eigen::SparseMatrix<double> at(2 * n, 3 * n);
  at.setFromTriplets(trip.begin(), trip.end());
  return at;
}

// Unknowns the tents leave free: one vertex per component (its translation) and the apex of
// every vertex without a ring. A unit pull to the rest position there removes the null space
// without bending the shape (the tents cannot see a translation).
std::vector<int> pinned_unknowns(const TentTopology& topology) {
  std::vector<int> pins;
  std::vector<bool> seen(static_cast<std::size_t>(topology.component_count), false);
  for (int v = 0; v < topology.vertex_count; ++v) {
    const auto c = static_cast<std::size_t>(topology.component[static_cast<std::size_t>(v)]);
    if (!seen[c]) pins.push_back(v);
    seen[c] = true;
    if (topology.ring(v).empty()) pins.push_back(topology.vertex_count + v);
  }
  return pins;
}

using Ldlt = Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>>;
using Rows3 = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

// P^T L^-T D^-1 L^-1 P b with the three coordinates side by side: one pass over L per
// direction instead of Eigen's one per right-hand side (the solve is bound by reading L).
Rows3 solve_three(const Ldlt& ldlt, const Rows3& b) {
  const Eigen::SparseMatrix<double>& l = ldlt.matrixL().nestedExpression();  // strictly lower
  const Eigen::VectorXd& d = ldlt.vectorD();
  Rows3 y = ldlt.permutationP() * b;
  const Eigen::Index n = l.outerSize();
  const int* outer = l.outerIndexPtr();
  const int* inner = l.innerIndexPtr();
  const double* value = l.valuePtr();
  for (Eigen::Index j = 0; j < n; ++j) {
    const Eigen::RowVector3d yj = y.row(j);
    for (int k = outer[j]; k < outer[j + 1]; ++k) y.row(inner[k]) -= value[k] * yj;
  }
  y.array().colwise() /= d.array();
  for (Eigen::Index j = n - 1; j >= 0; --j) {
    Eigen::RowVector3d yj = y.row(j);
    for (int k = outer[j]; k < outer[j + 1]; ++k) yj -= value[k] * y.row(inner[k]);
    y.row(j) = yj;
  }
  return ldlt.permutationPinv() * y;
}

}  // namespace

Result<VtcSource> VtcSource::create(TentTopology topology, const Points& neutral) {
  if (auto ok = check_points(topology, neutral, "the source neutral"); !ok) return ok.failure();
  VtcSource s;
  s.inverses_ = tent_inverses(topology, neutral);
  s.topology_ = std::move(topology);
  s.neutral_ = neutral;
  return s;
}

Result<Transformations> VtcSource::transformations(const Points& expression) const {
  if (auto ok = check_points(topology_, expression, "the source expression"); !ok)
    return ok.failure();
  const Points apexes = tent_apexes(topology_, expression);
  Transformations q(static_cast<std::size_t>(topology_.vertex_count));
  for (int v = 0; v < topology_.vertex_count; ++v)
    q[static_cast<std::size_t>(v)] =
        tent_coordinates(topology_, expression, apexes, v) * inverses_[static_cast<std::size_t>(v)];
  return q;
}

struct VtcTarget::State {
  TentTopology topology;
  Points neutral;
  std::vector<double> weights;  // per vertex, on its three rows
  Eigen::SparseMatrix<double> a_t;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver;
  Eigen::MatrixXd pin_rhs;                // 2N x 3: the pull's right-hand side
  std::vector<std::vector<int>> members;  // vertices per component
  double factor_ms = 0;
};

VtcTarget::VtcTarget(std::unique_ptr<State> state) : state_(std::move(state)) {}
VtcTarget::VtcTarget(VtcTarget&&) noexcept = default;
VtcTarget& VtcTarget::operator=(VtcTarget&&) noexcept = default;
VtcTarget::~VtcTarget() = default;
const TentTopology& VtcTarget::topology() const {
  return state_->topology;
}
const Points& VtcTarget::neutral() const {
  return state_->neutral;
}
double VtcTarget::factor_ms() const {
  return state_->factor_ms;
}
long long VtcTarget::factor_nonzeros() const {
  return state_->solver.matrixL().nestedExpression().nonZeros();
}

Result<VtcTarget> VtcTarget::create(TentTopology topology, const Points& neutral) {
  if (auto ok = check_points(topology, neutral, "the target neutral"); !ok) return ok.failure();
  const auto t0 = Clock::now();
  auto s = std::make_unique<State>();
  const int n = topology.vertex_count;
  s->weights = row_weights(topology, neutral);
  s->a_t = tent_system_transposed(topology, tent_inverses(topology, neutral), s->weights);
  Eigen::SparseMatrix<double> ata = s->a_t * s->a_t.transpose();
  const Points apexes = tent_apexes(topology, neutral);
  s->pin_rhs.setZero(2 * n, 3);
  // The pull's weight is the matrix's mean diagonal, so it neither swamps nor vanishes.
  const double weight = std::max(ata.diagonal().mean(), 1e-12);
  for (int u : pinned_unknowns(topology)) {
    ata.coeffRef(u, u) += weight;
    s->pin_rhs.row(u) = weight * (u < n ? neutral.row(u) : apexes.row(u - n));
  }
  s->solver.compute(ata);
  if (s->solver.info() != Eigen::Success)
    return fail("VTC: the target's system could not be factored (degenerate target mesh?)");
  s->members.resize(static_cast<std::size_t>(topology.component_count));
  for (int v = 0; v < n; ++v)
    s->members[static_cast<std::size_t>(topology.component[static_cast<std::size_t>(v)])].push_back(
        v);
  s->topology = std::move(topology);
  s->neutral = neutral;
  s->factor_ms = ms_since(t0);
  return VtcTarget(std::move(s));
}

namespace {

// Shifts each component so its stillest quarter (by |motion|) moves as `motion` says.
void fix_translation(const std::vector<std::vector<int>>& members, const Points& rest,
                     const Points& motion, Points& x) {
  for (const auto& vs : members) {
    std::vector<std::pair<double, int>> by_motion;
    by_motion.reserve(vs.size());
    for (int v : vs) by_motion.emplace_back(motion.row(v).squaredNorm(), v);
    const std::size_t keep = std::max<std::size_t>(1, vs.size() / 4);
    std::nth_element(by_motion.begin(), by_motion.begin() + static_cast<std::ptrdiff_t>(keep - 1),
                     by_motion.end());
    Eigen::RowVector3d shift = Eigen::RowVector3d::Zero();
    for (std::size_t i = 0; i < keep; ++i) {
      const int v = by_motion[i].second;
      shift += motion.row(v) - (x.row(v) - rest.row(v));
    }
    shift /= static_cast<double>(keep);
    for (int v : vs) x.row(v) += shift;
  }
}

}  // namespace

Result<Points> VtcTarget::solve(std::span<const Eigen::Matrix3d> q, const Points& motion) const {
  const State& s = *state_;
  const int n = s.topology.vertex_count;
  if (q.size() != static_cast<std::size_t>(n))
    return fail("VTC: " + std::to_string(q.size()) + " transformations for a target of " +
                std::to_string(n) + " vertices");
  if (auto ok = check_points(s.topology, motion, "the motion"); !ok) return ok.failure();
  Rows3 b(3 * n, 3);
  for (int v = 0; v < n; ++v)
    b.middleRows(3 * v, 3) =
        q[static_cast<std::size_t>(v)].transpose() * s.weights[static_cast<std::size_t>(v)];
  const Rows3 x = solve_three(s.solver, s.a_t * b + s.pin_rhs);
  if (!x.allFinite()) return fail("VTC: the solve diverged (non-finite source transformations?)");
  Points out = x.topRows(n);
  fix_translation(s.members, s.neutral, motion, out);
  return out;
}

Result<Points> vtc_transfer(const VtcSource& source, const VtcTarget& target,
                            const Points& source_expression) {
  if (source.topology().vertex_count != target.topology().vertex_count)
    return fail("VTC: source and target have different vertex counts (" +
                std::to_string(source.topology().vertex_count) + " and " +
                std::to_string(target.topology().vertex_count) +
                "); meshes of different topology need a correspondence first");
  auto q = source.transformations(source_expression);
  if (!q) return q.failure();
  return target.solve(*q, source_expression - source.neutral());
}

}  // namespace fb
