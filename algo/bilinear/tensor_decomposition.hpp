// N-mode SVD of the data tensor T (3V coordinates x identities x expressions) without factoring
// the vertex mode (FaceWarehouse eq. 8-9):
//
//   C = T x_2 U_id^T x_3 U_exp^T,   T ~= C_r x_2 U~_id x_3 U~_exp
//
// U_id / U_exp are the left singular vectors of the mode-2 / mode-3 unfoldings, found as the
// eigenvectors of their Gram matrices (I x I and E x E), which never needs the unfoldings
// themselves:
//   G_id[i, i'] = sum_e <T[:, i, e], T[:, i', e]>,   G_exp[e, e'] = sum_i <T[:, i, e], T[:, i,
//   e']>.
//
// Two tensor forms:
//  - DataTensor: every slice stored (personal rigs from sessions). 150 x 54 slices of 11,248
//    vertices would be 1.1 GB of floats, so this is for tens of subjects.
//  - FactoredTensor: every slice is basis * a(i, e) for a shared basis (rows x K) and small
//    coefficient vectors. The bootstrap tensor from the linear face model is exactly this, with
//    basis = [neutral, identity modes, expression deltas] and a(i, e) = [1, c_i, onehot(e)].
//    Then <slice, slice'> = a^T (basis^T basis) a', so the Grams cost K x K per pair and the core
//    is basis x_1 (A x_2 U_id^T x_3 U_exp^T): one (rows x K) * (K x Kid Kexp) product.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "algo/core/result.hpp"

namespace fb {

struct DataTensor {
  int rows = 0;  // 3V
  int identities = 0;
  int expressions = 0;
  std::vector<float> data;  // slice (i, e) at (e * identities + i) * rows, rows floats
};

struct FactoredTensor {
  int rows = 0;
  int identities = 0;
  int expressions = 0;
  Eigen::MatrixXf basis;         // rows x K
  Eigen::MatrixXd coefficients;  // K x (identities * expressions), column e * identities + i
};

// The untruncated mode factors, eigenvalues descending.
struct ModeFactors {
  Eigen::MatrixXd identity;    // identities x identities, orthonormal columns
  Eigen::MatrixXd expression;  // expressions x expressions
  Eigen::VectorXd identity_spectrum;
  Eigen::VectorXd expression_spectrum;
};

struct TruncatedTensor {
  int rows = 0;
  int id_knobs = 0;
  int exp_knobs = 0;
  std::vector<float> core;            // Kexp * Kid blocks of rows floats (block b * Kid + a)
  Eigen::MatrixXd identity;           // U~_id, identities x Kid
  Eigen::MatrixXd expression;         // U~_exp, expressions x Kexp
  Eigen::VectorXd identity_spectrum;  // all eigenvalues
  Eigen::VectorXd expression_spectrum;
};

Result<ModeFactors> mode_factors(const DataTensor& tensor);
// The factors of given Gram matrices (what mode_factors computes them from; the streaming
// build accumulates them itself, streaming_decomposition.hpp).
ModeFactors factors_from_grams(const Eigen::MatrixXd& identity_gram,
                               const Eigen::MatrixXd& expression_gram);
Result<ModeFactors> mode_factors(const FactoredTensor& tensor);

// Core of the truncation to (id_knobs, exp_knobs). Errors on knobs out of 1..identities /
// 1..expressions or inconsistent tensor sizes.
Result<TruncatedTensor> truncate(const DataTensor& tensor, const ModeFactors& factors, int id_knobs,
                                 int exp_knobs);
Result<TruncatedTensor> truncate(const FactoredTensor& tensor, const ModeFactors& factors,
                                 int id_knobs, int exp_knobs);
// The truncation of a rows x identities x expressions tensor before its core is filled in: the
// knobs checked as truncate() does, U~_id, U~_exp and the spectra from `factors` (shared with
// the streaming core build, streaming_decomposition.hpp).
Result<TruncatedTensor> truncated_factors(const ModeFactors& factors, int rows, int identities,
                                          int expressions, int id_knobs, int exp_knobs);

// Factored core in coefficient space: K x (Kexp * Kid), column b * Kid + a; the dense core is
// basis * this. Lets evaluations of many knob counts work in K dimensions.
Eigen::MatrixXd factored_core(const FactoredTensor& tensor, const Eigen::MatrixXd& identity,
                              const Eigen::MatrixXd& expression);

}  // namespace fb
