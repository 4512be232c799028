// The N-mode SVD of tensor_decomposition.hpp fed one identity at a time (issue 38, item 4), so
// a tensor of hundreds of subjects (7.3 MB each at 11,248 vertices x 54 expressions) is never
// held whole. The caller reads identity i's expressions (E slices of `rows` floats) from
// wherever they live and hands them over; nothing here does I/O.
//
//   GramAccumulator: G_exp = sum_i T_i^T T_i (E x E) adds up one identity at a time. G_id[i, i']
//   = <vec T_i, vec T_i'> needs pairs, so the accumulator keeps a panel of up to `panel`
//   identities and asks for the identities before the panel again in each later pass
//   (next_identity() says which one it wants): passes = ceil(N / panel), identities read
//   sum_p min(N, (p + 1) panel). Streamed identities are batched so the products are GEMMs.
//   The vertex mode is never factored.
//   CoreAccumulator: C_r = T x_2 U~_id^T x_3 U~_exp^T, one pass, identity i adding
//   U~_id[i] (x) (T_i U~_exp).
//
// Products in float (GEMM speed), summed per expression slice in double, as the in-memory
// mode_factors() / truncate() do: the two agree to float round-off (tests/bilinear).
#pragma once

#include <cstddef>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "algo/bilinear/tensor_decomposition.hpp"
#include "algo/core/result.hpp"

namespace fb {

struct StreamShape {
  int rows = 0;  // 3V
  int identities = 0;
  int expressions = 0;
  std::size_t identity_floats() const {
    return static_cast<std::size_t>(rows) * static_cast<std::size_t>(expressions);
  }
};

// How many identities a panel of `memory_bytes` holds (at least 1, at most all).
int panel_for_memory(const StreamShape& shape, std::size_t memory_bytes);

class GramAccumulator {
 public:
  static Result<GramAccumulator> create(const StreamShape& shape, int panel);

  // The identity to feed next (0-based), or -1 when both Gram matrices are complete.
  int next_identity() const;
  // Identity `identity`'s expressions, slice e at [e * rows, (e + 1) * rows). Must be the one
  // next_identity() asked for (errors otherwise, and on a wrong size or a non-finite value).
  Result<void> add(int identity, std::span<const float> slices);

  int passes() const;
  long long identities_read() const { return reads_; }
  // The eigen-decompositions, once next_identity() is -1.
  Result<ModeFactors> factors() const;
  const Eigen::MatrixXd& identity_gram() const { return g_id_; }
  const Eigen::MatrixXd& expression_gram() const { return g_exp_; }

 private:
  GramAccumulator() = default;
  void flush_batch();
  void close_panel();

  StreamShape shape_;
  int panel_ = 0;
  int pass_ = 0;  // panel [pass * panel, min(N, (pass + 1) * panel))
  int next_ = 0;  // next identity wanted in this pass
  long long reads_ = 0;
  Eigen::MatrixXf panel_data_;  // identity_floats x panel
  Eigen::MatrixXf batch_;       // identity_floats x kBatch, identities before the panel
  std::vector<int> batch_ids_;
  Eigen::MatrixXd g_id_;
  Eigen::MatrixXd g_exp_;
};

class CoreAccumulator {
 public:
  // Keeps the leading id_knobs / exp_knobs factors (errors on knobs out of range).
  static Result<CoreAccumulator> create(const StreamShape& shape, const ModeFactors& factors,
                                        int id_knobs, int exp_knobs);
  // Each identity once, any order.
  Result<void> add(int identity, std::span<const float> slices);
  // The truncation, once every identity was added (errors otherwise).
  Result<TruncatedTensor> finish();

 private:
  CoreAccumulator() = default;
  void flush_batch();

  StreamShape shape_;
  TruncatedTensor out_;
  Eigen::MatrixXf u_exp_;    // E x Kexp
  Eigen::MatrixXf y_batch_;  // rows x (Kexp * kBatch): column b * kBatch + k
  Eigen::MatrixXf u_batch_;  // kBatch x Kid
  int batched_ = 0;
  std::vector<bool> seen_;
};

}  // namespace fb
