#include "algo/bilinear/tensor_decomposition.hpp"

#include <string>

#include <Eigen/Eigenvalues>

namespace fb {
namespace {

// Eigenvectors of a symmetric Gram matrix, eigenvalues descending (clamped at 0: round-off).
void sorted_eigen(const Eigen::MatrixXd& gram, Eigen::MatrixXd& vectors, Eigen::VectorXd& values) {
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> solver(gram);
  const int n = static_cast<int>(gram.rows());
  vectors.resize(n, n);
  values.resize(n);
  for (int k = 0; k < n; ++k) {
    vectors.col(k) = solver.eigenvectors().col(n - 1 - k);
    values[k] = std::max(0.0, solver.eigenvalues()[n - 1 - k]);
    // A deterministic sign: the largest-magnitude entry positive.
    Eigen::Index at = 0;
    vectors.col(k).cwiseAbs().maxCoeff(&at);
    if (vectors(at, k) < 0) vectors.col(k) *= -1.0;
  }
}

Result<void> check(const DataTensor& t) {
  if (t.rows <= 0 || t.identities <= 0 || t.expressions <= 0)
    return fail("tensor: empty (rows, identities and expressions must all be positive)");
  if (t.data.size() != static_cast<std::size_t>(t.rows) * t.identities * t.expressions)
    return fail("tensor: " + std::to_string(t.data.size()) + " values for " +
                std::to_string(t.rows) + " x " + std::to_string(t.identities) + " x " +
                std::to_string(t.expressions));
  return success();
}

Result<void> check(const FactoredTensor& t) {
  if (t.rows <= 0 || t.identities <= 0 || t.expressions <= 0 || t.basis.cols() == 0)
    return fail("tensor: empty factored tensor");
  if (t.basis.rows() != t.rows || t.coefficients.rows() != t.basis.cols() ||
      t.coefficients.cols() != static_cast<Eigen::Index>(t.identities) * t.expressions)
    return fail("tensor: factored tensor sizes do not match");
  return success();
}

}  // namespace

Result<TruncatedTensor> truncated_factors(const ModeFactors& f, int rows, int identities,
                                          int expressions, int id_knobs, int exp_knobs) {
  if (id_knobs < 1 || id_knobs > identities)
    return fail("identity knobs must be 1.." + std::to_string(identities) + " (the number of " +
                "identities), got " + std::to_string(id_knobs));
  if (exp_knobs < 1 || exp_knobs > expressions)
    return fail("expression knobs must be 1.." + std::to_string(expressions) + ", got " +
                std::to_string(exp_knobs));
  TruncatedTensor out;
  out.rows = rows;
  out.id_knobs = id_knobs;
  out.exp_knobs = exp_knobs;
  out.identity = f.identity.leftCols(id_knobs);
  out.expression = f.expression.leftCols(exp_knobs);
  out.identity_spectrum = f.identity_spectrum;
  out.expression_spectrum = f.expression_spectrum;
  return out;
}

ModeFactors factors_from_grams(const Eigen::MatrixXd& identity_gram,
                               const Eigen::MatrixXd& expression_gram) {
  ModeFactors f;
  sorted_eigen(identity_gram, f.identity, f.identity_spectrum);
  sorted_eigen(expression_gram, f.expression, f.expression_spectrum);
  return f;
}

Result<ModeFactors> mode_factors(const DataTensor& t) {
  if (auto ok = check(t); !ok) return ok.failure();
  const int n_id = t.identities, n_exp = t.expressions;
  const Eigen::Index rows = t.rows;
  Eigen::MatrixXd g_id = Eigen::MatrixXd::Zero(n_id, n_id);
  Eigen::MatrixXd g_exp = Eigen::MatrixXd::Zero(n_exp, n_exp);
  // Double products: the uncentred Gram is dominated by the mean face (the trailing
  // eigenvalues are ~1e-4 of the first), so float round-off there moved the truncated model by
  // ~0.01 mm between two float summation orders (docs/sync.md).
  Eigen::MatrixXd slice;
  for (int e = 0; e < n_exp; ++e) {
    slice = Eigen::Map<const Eigen::MatrixXf>(
                t.data.data() + static_cast<std::size_t>(e) * n_id * rows, rows, n_id)
                .cast<double>();
    g_id.selfadjointView<Eigen::Lower>().rankUpdate(slice.transpose());
  }
  g_id = g_id.selfadjointView<Eigen::Lower>();
  // Mode 3: M = the (rows * I) x E unfolding; one identity's rows at a time.
  const Eigen::Map<const Eigen::MatrixXf> m(t.data.data(), rows * n_id, n_exp);
  for (int i = 0; i < n_id; ++i) {
    slice = m.middleRows(i * rows, rows).cast<double>();
    g_exp.selfadjointView<Eigen::Lower>().rankUpdate(slice.transpose());
  }
  g_exp = g_exp.selfadjointView<Eigen::Lower>();
  return factors_from_grams(g_id, g_exp);
}

Result<ModeFactors> mode_factors(const FactoredTensor& t) {
  if (auto ok = check(t); !ok) return ok.failure();
  const int n_id = t.identities, n_exp = t.expressions;
  const Eigen::MatrixXd basis = t.basis.cast<double>();
  const Eigen::MatrixXd gram = basis.transpose() * basis;
  Eigen::MatrixXd g_id = Eigen::MatrixXd::Zero(n_id, n_id);
  Eigen::MatrixXd g_exp = Eigen::MatrixXd::Zero(n_exp, n_exp);
  std::vector<Eigen::MatrixXd> weighted(static_cast<std::size_t>(n_exp));
  for (int e = 0; e < n_exp; ++e) {
    const auto a_e = t.coefficients.middleCols(static_cast<Eigen::Index>(e) * n_id, n_id);
    weighted[static_cast<std::size_t>(e)] = gram * a_e;
    g_id.noalias() += a_e.transpose() * weighted[static_cast<std::size_t>(e)];
  }
  for (int e = 0; e < n_exp; ++e)
    for (int e2 = 0; e2 <= e; ++e2) {
      const auto a_e2 = t.coefficients.middleCols(static_cast<Eigen::Index>(e2) * n_id, n_id);
      const double v = a_e2.cwiseProduct(weighted[static_cast<std::size_t>(e)]).sum();
      g_exp(e, e2) = g_exp(e2, e) = v;
    }
  return factors_from_grams(g_id, g_exp);
}

Result<TruncatedTensor> truncate(const DataTensor& t, const ModeFactors& f, int id_knobs,
                                 int exp_knobs) {
  if (auto ok = check(t); !ok) return ok.failure();
  auto truncated = truncated_factors(f, t.rows, t.identities, t.expressions, id_knobs, exp_knobs);
  if (!truncated) return truncated.failure();
  TruncatedTensor& out = *truncated;
  const Eigen::Index rows = t.rows;
  const Eigen::MatrixXf u_id = out.identity.cast<float>();
  // Y: column e = vec(T_e U~_id) (rows x Kid); core = Y U~_exp.
  Eigen::MatrixXf y(rows * id_knobs, t.expressions);
  for (int e = 0; e < t.expressions; ++e) {
    const Eigen::Map<const Eigen::MatrixXf> te(
        t.data.data() + static_cast<std::size_t>(e) * t.identities * rows, rows, t.identities);
    Eigen::Map<Eigen::MatrixXf>(y.col(e).data(), rows, id_knobs).noalias() = te * u_id;
  }
  out.core.resize(static_cast<std::size_t>(rows) * id_knobs * exp_knobs);
  Eigen::Map<Eigen::MatrixXf>(out.core.data(), rows * id_knobs, exp_knobs).noalias() =
      y * out.expression.cast<float>();
  return truncated;
}

Eigen::MatrixXd factored_core(const FactoredTensor& t, const Eigen::MatrixXd& identity,
                              const Eigen::MatrixXd& expression) {
  const Eigen::Index k = t.basis.cols();
  const Eigen::Index id_knobs = identity.cols(), exp_knobs = expression.cols();
  Eigen::MatrixXd z(k * id_knobs, t.expressions);
  for (int e = 0; e < t.expressions; ++e)
    Eigen::Map<Eigen::MatrixXd>(z.col(e).data(), k, id_knobs).noalias() =
        t.coefficients.middleCols(static_cast<Eigen::Index>(e) * t.identities, t.identities) *
        identity;
  const Eigen::MatrixXd stacked = z * expression;  // (K * Kid) x Kexp
  return Eigen::Map<const Eigen::MatrixXd>(stacked.data(), k, id_knobs * exp_knobs);
}

Result<TruncatedTensor> truncate(const FactoredTensor& t, const ModeFactors& f, int id_knobs,
                                 int exp_knobs) {
  if (auto ok = check(t); !ok) return ok.failure();
  auto truncated = truncated_factors(f, t.rows, t.identities, t.expressions, id_knobs, exp_knobs);
  if (!truncated) return truncated.failure();
  TruncatedTensor& out = *truncated;
  const Eigen::MatrixXf coeffs = factored_core(t, out.identity, out.expression).cast<float>();
  out.core.resize(static_cast<std::size_t>(t.rows) * id_knobs * exp_knobs);
  Eigen::Map<Eigen::MatrixXf>(out.core.data(), t.rows, id_knobs * exp_knobs).noalias() =
      t.basis * coeffs;
  return truncated;
}

}  // namespace fb
