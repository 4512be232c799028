#include "algo/tracking/weight_solver.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include <Eigen/Cholesky>

namespace fb {
namespace {

// gram = A^T A for A = rows [first, first + count), in chunks of rows: Eigen's GEMM packs its
// operands into a workspace that it heap-allocates above 128 KB (EIGEN_STACK_ALLOCATION_LIMIT);
// 256 x 53 floats stay on the stack, so the steady state does not allocate (and it is no
// slower). A symmetric rank-k update (SYRK) builds the lower triangle only, half the
// multiply-adds of the full product; the upper triangle is then mirrored (the solver reads
// whole columns).
void set_gram(const RowMatrix& rows, int first, int count, ShapeMatrix& gram) {
  constexpr int kChunkRows = 256;
  gram.setZero();
  for (int start = first; start < first + count; start += kChunkRows) {
    const int n = std::min(kChunkRows, first + count - start);
    gram.selfadjointView<Eigen::Lower>().rankUpdate(rows.middleRows(start, n).transpose());
  }
  gram = gram.selfadjointView<Eigen::Lower>();
}

}  // namespace

void weight_standard_errors(const ShapeMatrix& information, float min_information,
                            ShapeVector& sigma) {
  const auto k = static_cast<int>(information.rows());
  sigma.setConstant(k, std::numeric_limits<float>::infinity());
  std::array<int, kMaxTrackedShapes> seen{};
  int m = 0;
  for (int j = 0; j < k; ++j)
    if (information(j, j) > min_information) seen[static_cast<std::size_t>(m++)] = j;
  if (m == 0) return;
  ShapeMatrix sub(m, m);
  for (int a = 0; a < m; ++a)
    for (int b = 0; b < m; ++b)
      sub(a, b) = information(seen[static_cast<std::size_t>(a)], seen[static_cast<std::size_t>(b)]);
  const Eigen::LDLT<ShapeMatrix> ldlt(sub);
  ShapeVector unit = ShapeVector::Zero(m), column(m);
  for (int a = 0; a < m; ++a) {
    // (I^-1)_aa = e_a^T I^-1 e_a: one solve per shape, m^3 in all (53 shapes: ~0.1 ms).
    unit[a] = 1.0f;
    column = ldlt.solve(unit);
    unit[a] = 0.0f;
    const float variance = column[a];
    if (variance > 0.0f) sigma[seen[static_cast<std::size_t>(a)]] = std::sqrt(variance);
  }
}

void WeightSolver::allocate(const WeightSolverOptions& options, float max_gate_mm, int n, int k) {
  options_ = options;
  max_gate_mm_ = max_gate_mm;
  weights = ShapeVector::Zero(k);
  previous_weights = ShapeVector::Zero(k);
  weight_sigma = ShapeVector::Zero(k);
  h.resize(k, k);
  h_hidden.resize(k, k);
  information.resize(k, k);
  landmark_gram.resize(k, k);
  g.resize(k);
  shape_sparsity.resize(k);
  rows.resize(n + 2 * 68, k);
  targets.resize(n + 2 * 68);
  found_sample.resize(static_cast<std::size_t>(n));
  found_residual.resize(static_cast<std::size_t>(n));
  found_target.resize(static_cast<std::size_t>(n));
  abs_scratch.resize(static_cast<std::size_t>(n));
}

void WeightSolver::solve(SubjectRig& rig, const TrackerCamera& camera, const OcclusionMask& mask,
                         const Image<float>& image, const PixelRect& b, const RigidPoseF& p,
                         int iterations, bool final, const TrackLandmarks* landmarks,
                         int& landmarks_used) {
  for (int it = 0; it < iterations; ++it) {
    float noise_sigma = 0.0f;
    const int depth_rows = add_depth_rows(rig, camera, mask, image, b, p, noise_sigma);
    int count = depth_rows;
    landmarks_used = 0;
    if (landmarks != nullptr && landmarks->points.size() >= 68)
      count = add_landmark_rows(rig, camera, mask, p, *landmarks, count, landmarks_used);
    if (count < 8) return;
    const int hidden_rows = add_hidden_rows(rig, mask, p, count);
    set_gram(rows, 0, count, h);
    g.noalias() = rows.topRows(count).transpose() * targets.head(count);
    if (hidden_rows > 0) set_gram(rows, count, hidden_rows, h_hidden);
    const bool last_solve = final && it == iterations - 1;
    if (options_.report_weight_sigma && last_solve && noise_sigma > 0.0f)
      estimate_weight_sigma(rig, depth_rows, count - depth_rows, noise_sigma);
    add_priors(rig, noise_sigma, last_solve, hidden_rows > 0);
    solve_bounded_lsq(h, g, 0.0f, 1.0f, weights);
    if (options_.support_sparsity < 1.0f) {
      // Relaxed lasso: the L1 term chose which shapes are on; on those it would also bias the
      // weight down by ~sparsity / H_jj (0.1-0.3 for a brow or lid, whose depth signal H_jj is
      // 45-300 mm^2), so they are solved again with the L1 weight scaled by support_sparsity.
      for (int j = 0; j < rig.k; ++j)
        if (weights[j] > 0.0f) g[j] += (1.0f - options_.support_sparsity) * shape_sparsity[j];
      solve_bounded_lsq(h, g, 0.0f, 1.0f, weights);
    }
    rig.update_current(weights);
  }
}

int WeightSolver::add_depth_rows(const SubjectRig& rig, const TrackerCamera& camera,
                                 const OcclusionMask& mask, const Image<float>& image,
                                 const PixelRect& b, const RigidPoseF& p, float& noise_sigma) {
  const Eigen::Matrix3f rt = p.r.transpose();
  int found = 0;
  for (int i = 0; i < rig.n; ++i) {
    Eigen::Vector3f x, nn, measured;
    if (!rig.facing_sample(p, i, x, nn)) continue;
    if (mask.hides_sample(i)) continue;
    if (!camera.measured_point(image, b, x, measured)) continue;
    // Data point in the model frame; the row says n_i . (B_i w) = n_i . (q - base_i).
    const Eigen::Vector3f xm = rig.sample(i);
    const Eigen::Vector3f& nm = rig.normals[static_cast<std::size_t>(i)];
    const Eigen::Vector3f q = rt * (measured - p.t);
    const auto f = static_cast<std::size_t>(found++);
    found_sample[f] = i;
    found_residual[f] = nm.dot(xm - q);
    found_target[f] = nm.dot(q - rig.base.segment<3>(3 * i));
  }
  // Robust scale: Tukey cut-off c = k * 1.4826 * median|r| (the MAD estimate of the noise
  // sigma, with the median of the current residuals centred at ~0), clamped to
  // [weight_min_gate_mm, icp_gate_mm]. An occluder's samples (residuals of centimetres) and
  // the ragged edges around it (a few mm) then get zero weight, while the clean face, whose
  // residual spread is the sensor noise, keeps its full weight.
  float cutoff = max_gate_mm_;
  noise_sigma = 0.0f;
  if ((options_.weight_tukey_k > 0.0f || options_.report_weight_sigma) && found > 16) {
    for (int f = 0; f < found; ++f)
      abs_scratch[static_cast<std::size_t>(f)] =
          std::abs(found_residual[static_cast<std::size_t>(f)]);
    auto mid = abs_scratch.begin() + found / 2;
    std::nth_element(abs_scratch.begin(), mid, abs_scratch.begin() + found);
    noise_sigma = 1.4826f * *mid;
  }
  if (options_.weight_tukey_k > 0.0f && noise_sigma > 0.0f) {
    cutoff = std::clamp(options_.weight_tukey_k * noise_sigma, options_.weight_min_gate_mm,
                        max_gate_mm_);
  }
  int count = 0;
  for (int f = 0; f < found; ++f) {
    const auto fi = static_cast<std::size_t>(f);
    const float w = tukey(found_residual[fi], cutoff);
    if (w <= 0.0f) continue;
    const float s = std::sqrt(w);
    rows.row(count) = s * rig.normal_rows.row(found_sample[fi]);
    targets[count] = s * found_target[fi];
    ++count;
  }
  return count;
}

int WeightSolver::add_landmark_rows(const SubjectRig& rig, const TrackerCamera& camera,
                                    const OcclusionMask& mask, const RigidPoseF& p,
                                    const TrackLandmarks& landmarks, int count,
                                    int& landmarks_used) {
  const float lw = options_.landmark_weight * landmark_scale(landmarks, options_.landmark_noise_px);
  for (int l = 17; l < 68; ++l) {
    if (!landmarks.valid.empty() && !landmarks.valid[static_cast<std::size_t>(l)]) continue;
    if (mask.hides_landmark(l)) continue;
    const Eigen::Vector3f x = rig.landmark_in_camera(p, l);
    if (x.z() <= 1.0f) continue;
    const Eigen::Vector2f r = camera.pixel_of(x) - landmarks.points[static_cast<std::size_t>(l)];
    const float rn = r.norm();
    const float hw = rn < options_.landmark_huber_px ? 1.0f : options_.landmark_huber_px / rn;
    // d proj / d x times R: the landmark's image motion per model-frame motion.
    const Eigen::Matrix<float, 2, 3> jr = camera.projection_jacobian(x) * p.r;
    const float s = std::sqrt(lw * hw);
    for (int a = 0; a < 2; ++a) {
      // Linearised at the current w: J w_new = J w - r.
      rows.row(count) = s * (jr(a, 0) * rig.expression_at_landmarks.row(3 * l) +
                             jr(a, 1) * rig.expression_at_landmarks.row(3 * l + 1) +
                             jr(a, 2) * rig.expression_at_landmarks.row(3 * l + 2));
      targets[count] = rows.row(count).dot(weights) - s * r[a];
      ++count;
    }
    ++landmarks_used;
  }
  return count;
}

int WeightSolver::add_hidden_rows(const SubjectRig& rig, const OcclusionMask& mask,
                                  const RigidPoseF& p, int count) {
  // Samples under an occluder are imputed at the previous frame's weights with weight
  // hidden_hold: rows n_i . B_i (w - w_prev) = 0. A shape mostly under the plate then holds
  // instead of following the few samples of it still in view, which otherwise pull it (and,
  // through the shared samples, the visible shapes) to whatever fits the plate's ragged edge.
  int hidden_rows = 0;
  if (!mask.on || options_.hidden_hold <= 0.0f) return 0;
  const float s = std::sqrt(options_.hidden_hold);
  for (int i = 0; i < rig.n; ++i) {
    if (!mask.samples[static_cast<std::size_t>(i)]) continue;
    Eigen::Vector3f x, nn;
    if (!rig.facing_sample(p, i, x, nn)) continue;
    rows.row(count + hidden_rows++) = s * rig.normal_rows.row(i);
  }
  return hidden_rows;
}

void WeightSolver::add_priors(SubjectRig& rig, float noise_sigma, bool last_solve,
                              bool hidden_rows) {
  const int k = rig.k;
  // The data rows are in mm^2 and the L1 weight was set for the sensor's usual noise: a
  // noisier frame (correlated disparity noise, a worse unit, hair) gives each mm^2 less
  // evidence, so the L1 weight grows with the frame's noise variance (MAD) over the reference.
  float prior_scale = 1.0f;
  if (options_.prior_noise_reference_mm > 0.0f && noise_sigma > 0.0f) {
    const float ratio = noise_sigma / options_.prior_noise_reference_mm;
    prior_scale = std::clamp(ratio * ratio, 1.0f, options_.max_prior_noise_scale);
  }
  // The L1 weight follows the signal this frame's rows give each shape: a shape whose region
  // is hidden (an occluder, the far side of a turned head) has no data, and a weight sized for
  // the whole face would drive it to 0 against the temporal term within a frame or two.
  // A low-signal shape that was on in the previous frame keeps a lighter one (see
  // WeightSolverOptions::on_shape_sparsity).
  for (int j = 0; j < k; ++j) {
    const bool continuing = previous_weights[j] > options_.on_shape_min_weight &&
                            rig.full_signal[j] < options_.on_shape_max_signal * rig.signal_median;
    shape_sparsity[j] =
        prior_scale * options_.sparsity *
        std::pow(std::max(h(j, j), 0.0f) / rig.signal_median, options_.sparsity_signal_power) *
        (continuing ? options_.on_shape_sparsity : 1.0f);
  }
  const float lt = options_.temporal_weight;
  if (options_.stale_temporal_floor < 1.0f) {
    // A shape hidden on the previous frame (seen_fraction: its signal then over its
    // whole-face signal) only held its value: the temporal term gets that fraction of its
    // weight (at least the floor), so a region coming out from under an occluder follows its
    // data at once. The ridge scales with this frame's fraction, so a hidden shape holds
    // (shape_ridge = ridge + the weak-shape prior; only the ridge part scales).
    for (int j = 0; j < k; ++j) {
      const float now = std::clamp(h(j, j) / rig.full_signal[j], 0.0f, 1.0f);
      const float ltj = lt * std::clamp(rig.seen_fraction[j], options_.stale_temporal_floor, 1.0f);
      h(j, j) += ltj + rig.shape_ridge[j] - options_.ridge * (1.0f - now);
      g[j] += ltj * previous_weights[j];
      if (last_solve) rig.seen_fraction[j] = now;  // read above
    }
  } else {
    h.diagonal().array() += lt + rig.shape_ridge.array();
    g += lt * previous_weights;
  }
  g -= shape_sparsity;
  if (hidden_rows) {
    h += h_hidden;
    g.noalias() += h_hidden * previous_weights;
  }
  for (const auto& [a, b] : rig.antagonists) {
    // + mu w_a w_b in the cost: w >= 0, so it only charges the two being on together.
    const float mu = options_.antagonist_weight * std::sqrt(h(a, a) * h(b, b));
    h(a, b) += mu;
    h(b, a) += mu;
  }
}

void WeightSolver::estimate_weight_sigma(const SubjectRig& rig, int depth_rows, int landmark_rows,
                                         float depth_sigma_mm) {
  // Fisher information: the depth rows over the MAD noise of this frame's residuals; the
  // landmark rows carry sqrt(landmark_weight * landmark_scale) and a source's points have
  // noise_px = landmark_noise_px / sqrt(landmark_scale), so their row noise is
  // sqrt(landmark_weight) * landmark_noise_px whatever the source. Robust weights stay in the
  // rows: a down-weighted sample informs less. `h` holds the Gram matrix of all the rows
  // (depth and landmarks, before the priors), so only the landmark rows' is built again.
  const float depth_variance = depth_sigma_mm * depth_sigma_mm;
  information = h / depth_variance;
  if (landmark_rows > 0) {
    set_gram(rows, depth_rows, landmark_rows, landmark_gram);
    information += landmark_gram * (1.0f / (options_.landmark_weight * options_.landmark_noise_px *
                                            options_.landmark_noise_px) -
                                    1.0f / depth_variance);
  }
  weight_standard_errors(information, 1e-3f * rig.signal_median / depth_variance, weight_sigma);
}

}  // namespace fb
