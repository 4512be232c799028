#include "algo/bilinear/streaming_decomposition.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

namespace fb {
namespace {

constexpr int kGramBatch = 8;   // streamed identities per GEMM against the panel
constexpr int kCoreBatch = 16;  // identities per update of the core

Result<void> check_slices(const StreamShape& shape, int identity, std::span<const float> slices) {
  if (identity < 0 || identity >= shape.identities)
    return fail("identity " + std::to_string(identity) + " is not in 0.." +
                std::to_string(shape.identities - 1));
  if (slices.size() != shape.identity_floats())
    return fail("identity " + std::to_string(identity) + ": " + std::to_string(slices.size()) +
                " values, expected " + std::to_string(shape.identity_floats()) + " (" +
                std::to_string(shape.expressions) + " expressions of " +
                std::to_string(shape.rows) + ")");
  for (float v : slices)
    if (!std::isfinite(v))
      return fail("identity " + std::to_string(identity) + " has a non-finite coordinate");
  return success();
}

Result<void> check_shape(const StreamShape& s) {
  if (s.rows <= 0 || s.identities <= 0 || s.expressions <= 0)
    return fail("tensor: empty (rows, identities and expressions must all be positive)");
  return success();
}

}  // namespace

int panel_for_memory(const StreamShape& shape, std::size_t memory_bytes) {
  const std::size_t per = std::max<std::size_t>(1, shape.identity_floats() * sizeof(float));
  const std::size_t n = memory_bytes / per;
  return static_cast<int>(std::clamp<std::size_t>(n, 1, std::max(1, shape.identities)));
}

Result<GramAccumulator> GramAccumulator::create(const StreamShape& shape, int panel) {
  if (auto ok = check_shape(shape); !ok) return ok.failure();
  if (panel < 1) return fail("the panel must hold at least one identity");
  GramAccumulator a;
  a.shape_ = shape;
  a.panel_ = std::min(panel, shape.identities);
  a.g_id_ = Eigen::MatrixXd::Zero(shape.identities, shape.identities);
  a.g_exp_ = Eigen::MatrixXd::Zero(shape.expressions, shape.expressions);
  return a;
}

int GramAccumulator::passes() const {
  return (shape_.identities + panel_ - 1) / panel_;
}

// Pass p reads its panel [s, t) first, then the identities before it: s .. t-1, 0 .. s-1.
int GramAccumulator::next_identity() const {
  if (pass_ >= passes()) return -1;
  const int s = pass_ * panel_;
  const int t = std::min(shape_.identities, s + panel_);
  return next_ < t - s ? s + next_ : next_ - (t - s);
}

Result<void> GramAccumulator::add(int identity, std::span<const float> slices) {
  const int want = next_identity();
  if (want < 0) return fail("the Gram matrices are complete; no identity is wanted");
  if (identity != want)
    return fail("identity " + std::to_string(identity) + " fed where identity " +
                std::to_string(want) + " was wanted (follow next_identity())");
  if (auto ok = check_slices(shape_, identity, slices); !ok) return ok;
  ++reads_;
  const Eigen::Index rows = shape_.rows;
  const int s = pass_ * panel_;
  const int t = std::min(shape_.identities, s + panel_);
  const Eigen::Map<const Eigen::VectorXf> data(slices.data(),
                                               static_cast<Eigen::Index>(slices.size()));
  if (identity >= s) {
    if (identity == s) panel_data_.resize(data.size(), t - s);
    panel_data_.col(identity - s) = data;
    // Expression mode: each identity is in exactly one panel, so counted once.
    const Eigen::MatrixXd ti =
        Eigen::Map<const Eigen::MatrixXf>(slices.data(), rows, shape_.expressions).cast<double>();
    Eigen::MatrixXd block = Eigen::MatrixXd::Zero(shape_.expressions, shape_.expressions);
    block.selfadjointView<Eigen::Lower>().rankUpdate(ti.transpose());
    g_exp_ += block.selfadjointView<Eigen::Lower>().toDenseMatrix();
    if (identity == t - 1) close_panel();
  } else {
    if (batch_.cols() != kGramBatch) batch_.resize(data.size(), kGramBatch);
    batch_.col(static_cast<Eigen::Index>(batch_ids_.size())) = data;
    batch_ids_.push_back(identity);
    if (static_cast<int>(batch_ids_.size()) == kGramBatch || identity == s - 1) flush_batch();
  }
  ++next_;
  if (next_ == t) {  // pass done
    ++pass_;
    next_ = 0;
    if (pass_ >= passes()) {
      panel_data_.resize(0, 0);
      batch_.resize(0, 0);
    }
  }
  return success();
}

// G_id within the panel. Products in double, one expression slice at a time (see
// mode_factors(): float round-off of the uncentred Gram moves the trailing eigenvectors).
void GramAccumulator::close_panel() {
  const Eigen::Index rows = shape_.rows, p = panel_data_.cols();
  const int s = pass_ * panel_;
  Eigen::MatrixXd block = Eigen::MatrixXd::Zero(p, p), slice;
  for (int e = 0; e < shape_.expressions; ++e) {
    slice = panel_data_.middleRows(e * rows, rows).cast<double>();
    block.selfadjointView<Eigen::Lower>().rankUpdate(slice.transpose());
  }
  g_id_.block(s, s, p, p) = block.selfadjointView<Eigen::Lower>().toDenseMatrix();
}

// G_id between the panel and a batch of identities before it.
void GramAccumulator::flush_batch() {
  const auto nb = static_cast<Eigen::Index>(batch_ids_.size());
  if (nb == 0) return;
  const Eigen::Index rows = shape_.rows, p = panel_data_.cols();
  const int s = pass_ * panel_;
  Eigen::MatrixXd cross = Eigen::MatrixXd::Zero(p, nb), a, b;
  for (int e = 0; e < shape_.expressions; ++e) {
    a = panel_data_.middleRows(e * rows, rows).cast<double>();
    b = batch_.middleRows(e * rows, rows).leftCols(nb).cast<double>();
    cross.noalias() += a.transpose() * b;
  }
  for (Eigen::Index k = 0; k < nb; ++k) {
    const int j = batch_ids_[static_cast<std::size_t>(k)];
    g_id_.block(s, j, p, 1) = cross.col(k);
    g_id_.block(j, s, 1, p) = cross.col(k).transpose();
  }
  batch_ids_.clear();
}

Result<ModeFactors> GramAccumulator::factors() const {
  if (next_identity() >= 0)
    return fail("the Gram matrices are not complete: identity " + std::to_string(next_identity()) +
                " of pass " + std::to_string(pass_ + 1) + " is still wanted");
  return factors_from_grams(g_id_, g_exp_);
}

Result<CoreAccumulator> CoreAccumulator::create(const StreamShape& shape,
                                                const ModeFactors& factors, int id_knobs,
                                                int exp_knobs) {
  if (auto ok = check_shape(shape); !ok) return ok.failure();
  if (factors.identity.rows() != shape.identities || factors.expression.rows() != shape.expressions)
    return fail("the mode factors are for another tensor size");
  auto truncated = truncated_factors(factors, shape.rows, shape.identities, shape.expressions,
                                     id_knobs, exp_knobs);
  if (!truncated) return truncated.failure();
  CoreAccumulator c;
  c.shape_ = shape;
  TruncatedTensor& o = c.out_;
  o = std::move(*truncated);
  o.core.assign(static_cast<std::size_t>(shape.rows) * id_knobs * exp_knobs, 0.0f);
  c.u_exp_ = o.expression.cast<float>();
  c.y_batch_.resize(shape.rows, static_cast<Eigen::Index>(exp_knobs) * kCoreBatch);
  c.u_batch_.resize(kCoreBatch, id_knobs);
  c.seen_.assign(static_cast<std::size_t>(shape.identities), false);
  return c;
}

Result<void> CoreAccumulator::add(int identity, std::span<const float> slices) {
  if (auto ok = check_slices(shape_, identity, slices); !ok) return ok;
  if (seen_[static_cast<std::size_t>(identity)])
    return fail("identity " + std::to_string(identity) + " was added to the core twice");
  seen_[static_cast<std::size_t>(identity)] = true;
  const Eigen::Map<const Eigen::MatrixXf> ti(slices.data(), shape_.rows, shape_.expressions);
  const Eigen::MatrixXf y = ti * u_exp_;  // rows x Kexp
  for (int b = 0; b < out_.exp_knobs; ++b) y_batch_.col(b * kCoreBatch + batched_) = y.col(b);
  u_batch_.row(batched_) = out_.identity.row(identity).cast<float>();
  if (++batched_ == kCoreBatch) flush_batch();
  return success();
}

// core[:, b * Kid + a] += sum_k Y_k[:, b] U~_id[i_k, a] over the batch.
void CoreAccumulator::flush_batch() {
  if (batched_ == 0) return;
  const Eigen::Index kid = out_.id_knobs;
  Eigen::Map<Eigen::MatrixXf> core(out_.core.data(), shape_.rows, kid * out_.exp_knobs);
  for (int b = 0; b < out_.exp_knobs; ++b)
    core.middleCols(b * kid, kid).noalias() +=
        y_batch_.middleCols(static_cast<Eigen::Index>(b) * kCoreBatch, batched_) *
        u_batch_.topRows(batched_);
  batched_ = 0;
}

Result<TruncatedTensor> CoreAccumulator::finish() {
  const auto missing = std::count(seen_.begin(), seen_.end(), false);
  if (missing > 0)
    return fail("the core is missing " + std::to_string(missing) + " of " +
                std::to_string(shape_.identities) + " identities");
  flush_batch();
  y_batch_.resize(0, 0);
  return std::move(out_);
}

}  // namespace fb
