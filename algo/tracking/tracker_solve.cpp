// FaceTracker stage: one frame's fit. The occlusion mask, projective point-to-plane ICP of the
// current face against the smoothed depth, and the blendshape weights by bounded least squares
// on the same samples plus the 2D landmarks, with the temporal, sparsity and occlusion priors.
#include <algorithm>
#include <cmath>
#include <numeric>

#include <Eigen/Cholesky>

#include "algo/tracking/face_tracker_state.hpp"

namespace fb {

using namespace tracker_detail;

void FaceTracker::State::mark_occluded(const Image<float>& image, const Box& b, const Pose& p,
                                       const TrackLandmarks* landmarks) {
  // Visibility: a sample is hidden when the depth at its pixel, or at one of 8 pixels
  // occluder_radius_px away, is nearer than the model point by more than occluder_margin_mm:
  // something (a hand) is in front of the face there. The margin is above the face's own
  // relief (the nose stands ~30 mm off the cheeks), so the face never hides itself. Hidden
  // samples leave the pose, the weights and the robust scale: the occluder's residuals
  // (centimetres) would otherwise inflate the MAD and so the Tukey cut-off, and the face
  // samples along its rim (mixed depths, the projector shadow's edge) would pass the cut-off
  // and drag both. Made once per frame from the predicted pose.
  const float margin = options.occluder_margin_mm;
  mask_on = margin > 0.0f;
  if (!mask_on) return;
  // Pass 1, the sample's own pixel; pass 2 (only when pass 1 found an occluder: the common
  // unoccluded frame pays one read a sample) the 8 pixels around it.
  const int r = std::max(0, options.occluder_radius_px);
  const std::array<std::array<int, 2>, 8> offsets = {
      {{-r, 0}, {r, 0}, {0, -r}, {0, r}, {-r, -r}, {r, -r}, {-r, r}, {r, r}}};
  auto nearer_at = [&](int px, int py, float nearer) {
    if (px < b.x0 || py < b.y0 || px >= b.x1 || py >= b.y1) return false;
    const float d = image.pixels[static_cast<std::size_t>(py) * width + px];
    return d > 0.0f && d < nearer;
  };
  auto pixel = [&](int i, int& u, int& v, float& nearer) {
    const Eigen::Vector3f x = p.r * sample(i) + p.t;
    if (x.z() <= 1.0f) return false;
    const Eigen::Vector2f px = pixel_of(x);
    u = static_cast<int>(std::lround(px.x()));
    v = static_cast<int>(std::lround(px.y()));
    nearer = x.z() - margin;
    return true;
  };
  bool any = false;
  for (int i = 0; i < n; ++i) {
    int u = 0, v = 0;
    float nearer = 0.0f;
    const bool hidden = pixel(i, u, v, nearer) && nearer_at(u, v, nearer);
    occluded[static_cast<std::size_t>(i)] = hidden ? 1 : 0;
    any = any || hidden;
  }
  landmark_occluded.fill(0);
  if (!any) return;
  // A landmark is hidden by the same test at its model point or at the detected point (a
  // detector's point on the hand has the hand's depth): own pixel and the 8 around it.
  const bool detected = landmarks != nullptr && landmarks->points.size() >= 68;
  auto hidden_around = [&](int u, int v, float nearer) {
    if (nearer_at(u, v, nearer)) return true;
    for (std::size_t o = 0; o < offsets.size() && r > 0; ++o)
      if (nearer_at(u + offsets[o][0], v + offsets[o][1], nearer)) return true;
    return false;
  };
  for (int l = 0; l < 68; ++l) {
    const Eigen::Vector3f x = landmark_in_camera(p, l);
    if (x.z() <= 1.0f) continue;
    const float nearer = x.z() - margin;
    const Eigen::Vector2f px = pixel_of(x);
    bool hidden = hidden_around(static_cast<int>(std::lround(px.x())),
                                static_cast<int>(std::lround(px.y())), nearer);
    if (!hidden && detected) {
      const Eigen::Vector2f& q = landmarks->points[static_cast<std::size_t>(l)];
      hidden = hidden_around(static_cast<int>(std::lround(q.x())),
                             static_cast<int>(std::lround(q.y())), nearer);
    }
    landmark_occluded[static_cast<std::size_t>(l)] = hidden ? 1 : 0;
  }
  // A shape predictor places its points jointly: with most of the inner face covered, the
  // points that look free are placed by the covered ones too, so none is used.
  const int hidden_inner =
      std::accumulate(landmark_occluded.begin() + 17, landmark_occluded.end(), 0);
  if (hidden_inner > options.max_hidden_landmark_fraction * 51.0f) landmark_occluded.fill(1);
  if (r == 0) return;
  for (int i = 0; i < n; ++i) {
    auto& hidden = occluded[static_cast<std::size_t>(i)];
    int u = 0, v = 0;
    float nearer = 0.0f;
    if (hidden || !pixel(i, u, v, nearer)) continue;
    for (const auto& [dx, dy] : offsets) {
      if (nearer_at(u + dx, v + dy, nearer)) {
        hidden = 1;
        break;
      }
    }
  }
}

FaceTracker::State::IcpStats FaceTracker::State::icp(const Image<float>& image, const Box& b,
                                                     Pose& p, int iterations, float first_gate,
                                                     float gate) const {
  IcpStats stats;
  for (int it = 0; it < iterations; ++it) {
    // Gate shrinks geometrically from first_gate to gate over the first iterations.
    const float c = std::max(gate, first_gate * std::pow(0.5f, static_cast<float>(it)));
    const Eigen::Vector3f pivot = p.r * centroid + p.t;
    Eigen::Matrix<float, 6, 6> jtj = Eigen::Matrix<float, 6, 6>::Zero();
    Eigen::Matrix<float, 6, 1> jtr = Eigen::Matrix<float, 6, 1>::Zero();
    IcpStats s;
    double r2 = 0.0;
    for (int i = 0; i < n; ++i) {
      Eigen::Vector3f x, nn, q;
      if (!facing_sample(p, i, x, nn)) continue;
      const Eigen::Vector2f px = pixel_of(x);
      const float u = px.x(), v = px.y();
      if (u < 0.0f || v < 0.0f || u > width - 1.0f || v > height - 1.0f) continue;
      // Hidden samples are not expected to be seen: the inlier fraction of loss detection is of
      // the visible ones (min_inliers still reports a face covered entirely).
      if (mask_on && occluded[static_cast<std::size_t>(i)]) continue;
      ++s.facing;
      if (!measured_point(image, b, x, q)) continue;
      ++s.used;
      const float r = nn.dot(x - q);
      const float w = tukey(r, c);
      if (w <= 0.0f) continue;
      ++s.inliers;
      r2 += static_cast<double>(r) * r;
      Eigen::Matrix<float, 6, 1> j;
      j.head<3>() = (x - pivot).cross(nn);
      j.tail<3>() = nn;
      jtj.noalias() += w * j * j.transpose();
      jtr.noalias() += w * r * j;
    }
    s.rms = s.inliers > 0 ? static_cast<float>(std::sqrt(r2 / s.inliers)) : 1e9f;
    stats = s;
    if (s.inliers < 12) break;
    jtj.diagonal().array() += 1e-3f;
    const Eigen::Matrix<float, 6, 1> xi = jtj.ldlt().solve(-jtr);
    p.apply_twist(xi.head<3>(), xi.tail<3>(), pivot);
    const float angle = xi.head<3>().norm();
    // Orthonormalise now and then against float drift.
    if (it == iterations - 1) p.r = Eigen::Quaternionf(p.r).normalized().toRotationMatrix();
    if (angle < options.icp_converged_rad && xi.tail<3>().norm() < options.icp_converged_mm &&
        it > 0)
      break;
  }
  return stats;
}

void FaceTracker::State::solve_weights(const Image<float>& image, const Box& b, const Pose& p,
                                       int iterations, bool final, const TrackLandmarks* landmarks,
                                       int& landmarks_used) {
  const Eigen::Matrix3f rt = p.r.transpose();
  for (int it = 0; it < iterations; ++it) {
    int found = 0;
    for (int i = 0; i < n; ++i) {
      Eigen::Vector3f x, nn, measured;
      if (!facing_sample(p, i, x, nn)) continue;
      if (mask_on && occluded[static_cast<std::size_t>(i)]) continue;
      if (!measured_point(image, b, x, measured)) continue;
      // Data point in the model frame; the row says n_i . (B_i w) = n_i . (q - base_i).
      const Eigen::Vector3f xm = sample(i);
      const Eigen::Vector3f& nm = normals[static_cast<std::size_t>(i)];
      const Eigen::Vector3f q = rt * (measured - p.t);
      const auto f = static_cast<std::size_t>(found++);
      found_sample[f] = i;
      found_residual[f] = nm.dot(xm - q);
      found_target[f] = nm.dot(q - base.segment<3>(3 * i));
    }
    // Robust scale: Tukey cut-off c = k * 1.4826 * median|r| (the MAD estimate of the noise
    // sigma, with the median of the current residuals centred at ~0), clamped to
    // [weight_min_gate_mm, icp_gate_mm]. An occluder's samples (residuals of centimetres) and
    // the ragged edges around it (a few mm) then get zero weight, while the clean face, whose
    // residual spread is the sensor noise, keeps its full weight.
    float cutoff = options.icp_gate_mm;
    if (options.weight_tukey_k > 0.0f && found > 16) {
      for (int f = 0; f < found; ++f)
        abs_scratch[static_cast<std::size_t>(f)] =
            std::abs(found_residual[static_cast<std::size_t>(f)]);
      auto mid = abs_scratch.begin() + found / 2;
      std::nth_element(abs_scratch.begin(), mid, abs_scratch.begin() + found);
      cutoff = std::clamp(options.weight_tukey_k * 1.4826f * *mid, options.weight_min_gate_mm,
                          options.icp_gate_mm);
    }
    int count = 0;
    for (int f = 0; f < found; ++f) {
      const auto fi = static_cast<std::size_t>(f);
      const float w = tukey(found_residual[fi], cutoff);
      if (w <= 0.0f) continue;
      const float s = std::sqrt(w);
      rows.row(count) = s * normal_rows.row(found_sample[fi]);
      targets[count] = s * found_target[fi];
      ++count;
    }
    landmarks_used = 0;
    if (landmarks != nullptr && landmarks->points.size() >= 68) {
      const float lw = options.landmark_weight * landmark_scale(*landmarks);
      for (int l = 17; l < 68; ++l) {
        if (!landmarks->valid.empty() && !landmarks->valid[static_cast<std::size_t>(l)]) continue;
        if (mask_on && landmark_occluded[static_cast<std::size_t>(l)]) continue;
        const Eigen::Vector3f x = landmark_in_camera(p, l);
        if (x.z() <= 1.0f) continue;
        const Eigen::Vector2f r = pixel_of(x) - landmarks->points[static_cast<std::size_t>(l)];
        const float rn = r.norm();
        const float hw = rn < options.landmark_huber_px ? 1.0f : options.landmark_huber_px / rn;
        // d proj / d x times R: the landmark's image motion per model-frame motion.
        const Eigen::Matrix<float, 2, 3> jr = projection_jacobian(x) * p.r;
        const float s = std::sqrt(lw * hw);
        for (int a = 0; a < 2; ++a) {
          // Linearised at the current w: J w_new = J w - r.
          rows.row(count) = s * (jr(a, 0) * expression_at_landmarks.row(3 * l) +
                                 jr(a, 1) * expression_at_landmarks.row(3 * l + 1) +
                                 jr(a, 2) * expression_at_landmarks.row(3 * l + 2));
          targets[count] = rows.row(count).dot(weights) - s * r[a];
          ++count;
        }
        ++landmarks_used;
      }
    }
    if (count < 8) return;
    // Samples under an occluder are imputed at the previous frame's weights with weight
    // hidden_hold: rows n_i . B_i (w - w_prev) = 0. A shape mostly under the plate then holds
    // instead of following the few samples of it still in view, which otherwise pull it (and,
    // through the shared samples, the visible shapes) to whatever fits the plate's ragged edge.
    int hidden_rows = 0;
    if (mask_on && options.hidden_hold > 0.0f) {
      const float s = std::sqrt(options.hidden_hold);
      for (int i = 0; i < n; ++i) {
        if (!occluded[static_cast<std::size_t>(i)]) continue;
        Eigen::Vector3f x, nn;
        if (!facing_sample(p, i, x, nn)) continue;
        rows.row(count + hidden_rows++) = s * normal_rows.row(i);
      }
    }
    set_gram(rows, 0, count, h);
    g.noalias() = rows.topRows(count).transpose() * targets.head(count);
    if (hidden_rows > 0) set_gram(rows, count, hidden_rows, h_hidden);
    // The L1 weight follows the signal this frame's rows give each shape: a shape whose region
    // is hidden (an occluder, the far side of a turned head) has no data, and a weight sized for
    // the whole face would drive it to 0 against the temporal term within a frame or two.
    // A low-signal shape that was on in the previous frame keeps a lighter one (see
    // TrackerOptions::on_shape_sparsity).
    for (int j = 0; j < k; ++j) {
      const bool continuing = previous_weights[j] > options.on_shape_min_weight &&
                              full_signal[j] < options.on_shape_max_signal * signal_median;
      shape_sparsity[j] =
          options.sparsity *
          std::pow(std::max(h(j, j), 0.0f) / signal_median, options.sparsity_signal_power) *
          (continuing ? options.on_shape_sparsity : 1.0f);
    }
    const float lt = options.temporal_weight;
    if (options.stale_temporal_floor < 1.0f) {
      // A shape hidden on the previous frame (seen_fraction: its signal then over its
      // whole-face signal) only held its value: the temporal term gets that fraction of its
      // weight (at least the floor), so a region coming out from under an occluder follows its
      // data at once. The ridge scales with this frame's fraction, so a hidden shape holds
      // (shape_ridge = ridge + the weak-shape prior; only the ridge part scales).
      for (int j = 0; j < k; ++j) {
        const float now = std::clamp(h(j, j) / full_signal[j], 0.0f, 1.0f);
        const float ltj = lt * std::clamp(seen_fraction[j], options.stale_temporal_floor, 1.0f);
        h(j, j) += ltj + shape_ridge[j] - options.ridge * (1.0f - now);
        g[j] += ltj * previous_weights[j];
        if (final && it == iterations - 1) seen_fraction[j] = now;  // read above
      }
    } else {
      h.diagonal().array() += lt + shape_ridge.array();
      g += lt * previous_weights;
    }
    g -= shape_sparsity;
    if (hidden_rows > 0) {
      h += h_hidden;
      g.noalias() += h_hidden * previous_weights;
    }
    for (const auto& [a, b] : antagonists) {
      // + mu w_a w_b in the cost: w >= 0, so it only charges the two being on together.
      const float mu = options.antagonist_weight * std::sqrt(h(a, a) * h(b, b));
      h(a, b) += mu;
      h(b, a) += mu;
    }
    solve_bounded_lsq(h, g, 0.0f, 1.0f, weights);
    if (options.support_sparsity < 1.0f) {
      // Relaxed lasso: the L1 term chose which shapes are on; on those it would also bias the
      // weight down by ~sparsity / H_jj (0.1-0.3 for a brow or lid, whose depth signal H_jj is
      // 45-300 mm^2), so they are solved again with the L1 weight scaled by support_sparsity.
      for (int j = 0; j < k; ++j)
        if (weights[j] > 0.0f) g[j] += (1.0f - options.support_sparsity) * shape_sparsity[j];
      solve_bounded_lsq(h, g, 0.0f, 1.0f, weights);
    }
    update_current();
  }
}

}  // namespace fb
