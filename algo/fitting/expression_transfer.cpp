#include "algo/fitting/expression_transfer.hpp"
#include "algo/core/clock.hpp"

#include <chrono>
#include <cmath>
#include <optional>

#include <Eigen/Dense>
#include <Eigen/SparseCholesky>

namespace fb {

namespace {

// Frame of triangle (a, b, c) with the Sumner-Popovic fourth vertex.
Eigen::Matrix3d frame(std::span<const float> p, std::uint32_t a, std::uint32_t b, std::uint32_t c) {
  auto v = [&](std::uint32_t i) { return Eigen::Vector3d(p[3 * i], p[3 * i + 1], p[3 * i + 2]); };
  const Eigen::Vector3d e1 = v(b) - v(a), e2 = v(c) - v(a);
  const Eigen::Vector3d n = e1.cross(e2);
  const double len = std::sqrt(std::max(n.norm(), 1e-12));
  Eigen::Matrix3d m;
  m << e1, e2, n / len;
  return m;
}

}  // namespace

struct ExpressionTransfer::State {
  int vertex_count = 0;
  std::vector<std::uint32_t> triangles;
  std::vector<float> guide_neutral;
  std::vector<float> neutral;                   // S0
  std::vector<Eigen::Matrix3d> guide_inverse;   // V_0^-1 per triangle (source rest)
  std::vector<Eigen::Matrix3d> target_inverse;  // W^-1 per triangle (target rest)
  Eigen::SparseMatrix<double> a_t;              // A^T (unknowns x 3T)
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver;
  Eigen::MatrixXd anchor;                     // epsilon * rest positions of all unknowns
  std::vector<std::uint32_t> fixed_vertices;  // where the translation is pinned
  std::optional<RefineSystem> refine_system;
  std::vector<float> rest_transfer;  // transfer(G0): what a part's displacement is taken from
  double factor_ms = 0;
};

ExpressionTransfer::ExpressionTransfer(std::unique_ptr<State> state) : state_(std::move(state)) {}

std::span<const float> ExpressionTransfer::guide_neutral() const {
  return state_->guide_neutral;
}
std::span<const float> ExpressionTransfer::neutral() const {
  return state_->neutral;
}
std::span<const float> ExpressionTransfer::rest_transfer() const {
  return state_->rest_transfer;
}
ExpressionTransfer::ExpressionTransfer(ExpressionTransfer&&) noexcept = default;
ExpressionTransfer& ExpressionTransfer::operator=(ExpressionTransfer&&) noexcept = default;
ExpressionTransfer::~ExpressionTransfer() = default;
double ExpressionTransfer::factorization_ms() const {
  return state_->factor_ms;
}
const RefineSystem& ExpressionTransfer::refine_system() const {
  return *state_->refine_system;
}

Result<ExpressionTransfer> ExpressionTransfer::create(const FaceModel& model,
                                                      std::span<const float> neutral_fit,
                                                      std::span<const float> guide_neutral,
                                                      const RefineOptions& refine) {
  const std::size_t n3 = static_cast<std::size_t>(model.vertex_count) * 3;
  if (neutral_fit.size() != n3 || guide_neutral.size() != n3)
    return fail("deformation transfer: meshes must have the model's vertex count");
  const auto t0 = Clock::now();
  auto s = std::make_unique<State>();
  s->vertex_count = model.vertex_count;
  s->triangles = model.triangles;
  s->guide_neutral.assign(guide_neutral.begin(), guide_neutral.end());
  s->neutral.assign(neutral_fit.begin(), neutral_fit.end());
  const int nt = model.triangle_count();
  const int nv = model.vertex_count;
  const int unknowns = nv + nt;
  s->guide_inverse.resize(static_cast<std::size_t>(nt));
  s->target_inverse.resize(static_cast<std::size_t>(nt));
  std::vector<Eigen::Triplet<double>> trip;
  trip.reserve(static_cast<std::size_t>(nt) * 12);
  Eigen::MatrixXd rest(unknowns, 3);
  for (int i = 0; i < nv; ++i)
    for (int d = 0; d < 3; ++d) rest(i, d) = neutral_fit[static_cast<std::size_t>(3 * i + d)];
  for (int t = 0; t < nt; ++t) {
    const auto a = s->triangles[3 * t], b = s->triangles[3 * t + 1], c = s->triangles[3 * t + 2];
    const Eigen::Matrix3d g0 = frame(guide_neutral, a, b, c);
    const Eigen::Matrix3d w = frame(neutral_fit, a, b, c);
    s->guide_inverse[static_cast<std::size_t>(t)] = g0.inverse();
    const Eigen::Matrix3d wi = w.inverse();
    s->target_inverse[static_cast<std::size_t>(t)] = wi;
    rest.row(nv + t) = rest.row(a) + w.col(2).transpose();
    // Row (t, k) of A: column k of X W^-1 = sum_m (x_{m} - x_a) Wi(m, k), m over b, c, 4th.
    const int cols[3] = {static_cast<int>(b), static_cast<int>(c), nv + t};
    for (int k = 0; k < 3; ++k) {
      double sum = 0;
      for (int mm = 0; mm < 3; ++mm) {
        trip.emplace_back(cols[mm], 3 * t + k, wi(mm, k));  // stored transposed: A^T
        sum += wi(mm, k);
      }
      trip.emplace_back(static_cast<int>(a), 3 * t + k, -sum);
    }
  }
  s->fixed_vertices = model.rigid_vertices;
  if (s->fixed_vertices.empty())
    for (int i = model.face_vertex_count; i < nv; ++i)
      s->fixed_vertices.push_back(static_cast<std::uint32_t>(i));
  s->a_t.resize(unknowns, 3 * nt);
  s->a_t.setFromTriplets(trip.begin(), trip.end());
  // A tiny pull towards S0 removes the translation null space without biasing the shape.
  constexpr double kAnchor = 1e-6;
  Eigen::SparseMatrix<double> ata = s->a_t * s->a_t.transpose();
  for (int i = 0; i < unknowns; ++i) ata.coeffRef(i, i) += kAnchor;
  s->anchor = kAnchor * rest;
  s->solver.compute(ata);
  if (s->solver.info() != Eigen::Success)
    return fail("deformation transfer: factorization failed (degenerate fitted mesh?)");
  auto system = RefineSystem::create(model, RefineSystem::Points(rest.topRows(nv)),
                                     refine_system_options(refine));
  if (!system) return system.failure();
  s->refine_system.emplace(std::move(*system));
  ExpressionTransfer out(std::move(s));
  auto rest_transfer = out.transfer(guide_neutral);
  if (!rest_transfer) return rest_transfer.failure();
  out.state_->rest_transfer = std::move(*rest_transfer);
  out.state_->factor_ms = ms_since(t0);
  return out;
}

Result<std::vector<float>> ExpressionTransfer::transfer(
    std::span<const float> guide_expression) const {
  const State& s = *state_;
  if (guide_expression.size() != static_cast<std::size_t>(s.vertex_count) * 3)
    return fail("deformation transfer: the guide expression has the wrong vertex count");
  const int nt = static_cast<int>(s.triangles.size() / 3);
  // b(3t + k, coordinate) = Q_t(coordinate, k), Q_t = V_i V_0^-1.
  Eigen::MatrixXd b(3 * nt, 3);
  for (int t = 0; t < nt; ++t) {
    const Eigen::Matrix3d q = frame(guide_expression, s.triangles[3 * t], s.triangles[3 * t + 1],
                                    s.triangles[3 * t + 2]) *
                              s.guide_inverse[static_cast<std::size_t>(t)];
    b.middleRows(3 * t, 3) = q.transpose();
  }
  const Eigen::MatrixXd rhs = s.a_t * b + s.anchor;
  Eigen::MatrixXd x = s.solver.solve(rhs);
  if (!x.allFinite()) return fail("deformation transfer: the solve diverged");
  // Gradients fix the shape up to a translation: pin it so that the rigid (skull) vertices
  // move on average as they do in the guide (G_i - G_0).
  Eigen::RowVector3d shift = Eigen::RowVector3d::Zero();
  for (std::uint32_t v : s.fixed_vertices) {
    for (int d = 0; d < 3; ++d) {
      shift[d] += guide_expression[3 * v + d] - s.guide_neutral[3 * v + d];
      shift[d] -= x(v, d) - s.neutral[3 * v + d];
    }
  }
  if (!s.fixed_vertices.empty())
    x.rowwise() += shift / static_cast<double>(s.fixed_vertices.size());
  std::vector<float> out(static_cast<std::size_t>(s.vertex_count) * 3);
  for (int i = 0; i < s.vertex_count; ++i)
    for (int d = 0; d < 3; ++d)
      out[static_cast<std::size_t>(3 * i + d)] = static_cast<float>(x(i, d));
  return out;
}

}  // namespace fb
