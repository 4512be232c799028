#include "algo/fitting/refine_system.hpp"
#include "algo/core/clock.hpp"

#include <chrono>

#include <Eigen/SparseCholesky>

#include "algo/fitting/mesh_ops.hpp"

namespace fb {

struct RefineSystem::State {
  RefineSystemOptions options;
  Eigen::SparseMatrix<double> laplacian;
  Eigen::SparseMatrix<double> lap_free_t;  // w_lap L_F^T  (|F| x n)
  Eigen::SparseMatrix<double> lap_held;    // L_C         (n x n, columns of F zero)
  std::vector<int> free_vertices;
  std::vector<int> free_index;  // n, -1 for held vertices
  std::vector<char> position_term;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver;
  // The factor in plain arrays for the 3-column solve: P A P^T = L D L^T, L unit lower (CSC,
  // strictly lower part), perm[i] = P's image of row i.
  std::vector<int> perm;
  Eigen::VectorXd inv_diag;
  double factor_ms = 0;
};

RefineSystem::RefineSystem(std::unique_ptr<State> state) : state_(std::move(state)) {}
RefineSystem::RefineSystem(RefineSystem&&) noexcept = default;
RefineSystem& RefineSystem::operator=(RefineSystem&&) noexcept = default;
RefineSystem::~RefineSystem() = default;

const RefineSystemOptions& RefineSystem::options() const {
  return state_->options;
}
const Eigen::SparseMatrix<double>& RefineSystem::laplacian() const {
  return state_->laplacian;
}
const std::vector<int>& RefineSystem::free_vertices() const {
  return state_->free_vertices;
}
int RefineSystem::free_index(int v) const {
  return state_->free_index[static_cast<std::size_t>(v)];
}
bool RefineSystem::has_position_term(int v) const {
  return state_->position_term[static_cast<std::size_t>(v)] != 0;
}
double RefineSystem::factorization_ms() const {
  return state_->factor_ms;
}
std::size_t RefineSystem::factor_nonzeros() const {
  return static_cast<std::size_t>(state_->solver.matrixL().nestedExpression().nonZeros());
}

Result<RefineSystem> RefineSystem::create(const FaceModel& model, const Points& reference,
                                          const RefineSystemOptions& options) {
  const auto t0 = Clock::now();
  const int n = model.vertex_count;
  if (reference.rows() != n) return fail("refine: the reference mesh has the wrong vertex count");
  if (model.fitting_vertices.empty()) return fail("refine: the face model has no fitting vertices");
  auto s = std::make_unique<State>();
  s->options = options;
  s->laplacian = fitting_detail::cotangent_laplacian(reference, model.triangles);

  // F: fitting vertices grown by margin_rings rings over the triangles.
  std::vector<char> in_free(static_cast<std::size_t>(n), 0);
  s->position_term.assign(static_cast<std::size_t>(n), 0);
  for (std::uint32_t v : model.fitting_vertices) {
    in_free[v] = 1;
    s->position_term[v] = 1;
  }
  for (int ring = 0; ring < options.margin_rings; ++ring) {
    std::vector<char> grown = in_free;
    for (std::size_t t = 0; t + 2 < model.triangles.size(); t += 3) {
      const std::uint32_t a = model.triangles[t], b = model.triangles[t + 1],
                          c = model.triangles[t + 2];
      if (in_free[a] || in_free[b] || in_free[c]) grown[a] = grown[b] = grown[c] = 1;
    }
    in_free.swap(grown);
  }
  s->free_index.assign(static_cast<std::size_t>(n), -1);
  for (int v = 0; v < n; ++v)
    if (in_free[static_cast<std::size_t>(v)]) {
      s->free_index[static_cast<std::size_t>(v)] = static_cast<int>(s->free_vertices.size());
      s->free_vertices.push_back(v);
    }
  const int nf = static_cast<int>(s->free_vertices.size());

  // Column selections of L: L_F (n x |F|) and L_C (n x n with F's columns dropped).
  std::vector<Eigen::Triplet<double>> free_part, held_part;
  for (int col = 0; col < n; ++col)
    for (Eigen::SparseMatrix<double>::InnerIterator it(s->laplacian, col); it; ++it) {
      const int f = s->free_index[static_cast<std::size_t>(col)];
      if (f >= 0)
        free_part.emplace_back(static_cast<int>(it.row()), f, it.value());
      else
        held_part.emplace_back(static_cast<int>(it.row()), col, it.value());
    }
  Eigen::SparseMatrix<double> lap_free(n, nf);
  lap_free.setFromTriplets(free_part.begin(), free_part.end());
  s->lap_held.resize(n, n);
  s->lap_held.setFromTriplets(held_part.begin(), held_part.end());
  s->lap_free_t = options.w_lap * Eigen::SparseMatrix<double>(lap_free.transpose());

  Eigen::SparseMatrix<double> a = s->lap_free_t * lap_free;
  for (int f = 0; f < nf; ++f)
    a.coeffRef(f, f) +=
        options.anchor +
        (s->position_term[static_cast<std::size_t>(s->free_vertices[static_cast<std::size_t>(f)])]
             ? options.w_pos
             : 0.0);
  s->solver.compute(a);
  if (s->solver.info() != Eigen::Success)
    return fail("refine: sparse factorization failed (degenerate reference mesh?)");
  const auto& p = s->solver.permutationP().indices();
  s->perm.assign(p.data(), p.data() + p.size());
  s->inv_diag = s->solver.vectorD().cwiseInverse();
  s->factor_ms = ms_since(t0);
  return RefineSystem(std::move(s));
}

void RefineSystem::laplacian_rhs(const Points& target, const Points& held, Points& out) const {
  const State& s = *state_;
  out.noalias() = s.lap_free_t * (target - s.lap_held * held);
}

void RefineSystem::solve(Points& rhs) const {
  const State& s = *state_;
  const auto& l = s.solver.matrixL().nestedExpression();
  const int n = static_cast<int>(l.rows());
  const int* outer = l.outerIndexPtr();
  const int* inner = l.innerIndexPtr();
  const double* value = l.valuePtr();
  // Eigen's solve runs the triangular solves once per column; the factor (~1M entries) is what
  // the solve streams, so all three coordinates go through it together, one row of y per vertex.
  std::vector<double> y(static_cast<std::size_t>(3 * n));  // vertex-interleaved
  for (int i = 0; i < n; ++i) {
    double* row = &y[static_cast<std::size_t>(3 * s.perm[static_cast<std::size_t>(i)])];
    row[0] = rhs(i, 0);
    row[1] = rhs(i, 1);
    row[2] = rhs(i, 2);
  }
  // L z = y (forward, by columns), then z /= D.
  for (int j = 0; j < n; ++j) {
    const double a = y[3 * j], b = y[3 * j + 1], c = y[3 * j + 2];
    for (int p = outer[j]; p < outer[j + 1]; ++p) {
      double* yi = &y[static_cast<std::size_t>(3 * inner[p])];
      const double lij = value[p];
      yi[0] -= lij * a;
      yi[1] -= lij * b;
      yi[2] -= lij * c;
    }
  }
  for (int j = 0; j < n; ++j) {
    const double d = s.inv_diag[j];
    y[3 * j] *= d;
    y[3 * j + 1] *= d;
    y[3 * j + 2] *= d;
  }
  // L^T x = z (backward: row j of L^T is column j of L).
  for (int j = n - 1; j >= 0; --j) {
    double a = y[3 * j], b = y[3 * j + 1], c = y[3 * j + 2];
    for (int p = outer[j]; p < outer[j + 1]; ++p) {
      const double* yi = &y[static_cast<std::size_t>(3 * inner[p])];
      const double lij = value[p];
      a -= lij * yi[0];
      b -= lij * yi[1];
      c -= lij * yi[2];
    }
    y[3 * j] = a;
    y[3 * j + 1] = b;
    y[3 * j + 2] = c;
  }
  for (int i = 0; i < n; ++i) {
    const double* row = &y[static_cast<std::size_t>(3 * s.perm[static_cast<std::size_t>(i)])];
    rhs(i, 0) = row[0];
    rhs(i, 1) = row[1];
    rhs(i, 2) = row[2];
  }
}

}  // namespace fb
