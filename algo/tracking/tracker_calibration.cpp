// FaceTracker stage: calibration to a new person. The identity (the face model's identity PCA)
// and the calibration frames' poses fitted jointly to the first frames' depth and landmarks;
// then where this face's landmarks and depth samples sit relative to the fitted model.
#include <algorithm>
#include <cmath>

#include <Eigen/Cholesky>

#include "algo/tracking/face_tracker_state.hpp"

namespace fb {

using namespace tracker_detail;

float FaceTracker::State::calibrate() {
  // Identity and the calibration frames' poses by joint Gauss-Newton on the point-to-plane
  // residuals of all stored frames, r = n . (x - q) with x = R_f (neutral_i + U_i c) + t_f,
  // and a Tikhonov prior on c (coefficients are in sigma units). The unknowns are c (m) and a
  // twist per frame (6); the poses are eliminated by their Schur complement:
  //   (A + lambda I - sum_f B_f D_f^-1 B_f^T) dc = -(g_c + lambda c) + sum_f B_f D_f^-1 g_f,
  //   dp_f = -D_f^-1 (g_f + B_f^T dc),
  // A = sum w J_c J_c^T, B_f = sum w J_c J_p^T, D_f = sum w J_p J_p^T over frame f's rows.
  // Alternating the two blocks instead converged slowly along the directions where a change
  // of shape and a head rotation look alike, and stopped degrees short when the mean face
  // started a few degrees off (a held-out occluder take: 8.4 deg, its lids then untracked).
  // The projective association moves with every step, so the iterates end up circling the
  // minimum (|dc| ~ 0.4 sigma); the identity is their mean over the second half of the rounds.
  using PoseMatrix = Eigen::Matrix<double, 6, 6>;
  using PoseVector = Eigen::Matrix<double, 6, 1>;
  Eigen::MatrixXd a(modes, modes), schur(modes, modes), bd(modes, 6);
  Eigen::VectorXd gc(modes), rhs(modes), c_sum = Eigen::VectorXd::Zero(modes);
  std::vector<Eigen::MatrixXd> b_frames(static_cast<std::size_t>(calib_count),
                                        Eigen::MatrixXd(modes, 6));
  std::vector<PoseMatrix> d_frames(static_cast<std::size_t>(calib_count));
  std::vector<Eigen::LDLT<PoseMatrix>> d_solvers(static_cast<std::size_t>(calib_count));
  std::vector<PoseVector> g_frames(static_cast<std::size_t>(calib_count));
  Eigen::VectorXf row(modes);
  Eigen::VectorXd c = Eigen::VectorXd::Zero(modes);
  for (int j = 0; j < modes && j < static_cast<int>(identity.size()); ++j)
    c[j] = identity[static_cast<std::size_t>(j)];
  std::vector<float> coefficients(static_cast<std::size_t>(modes));
  auto rebuild = [&](bool keep_rigid) {
    for (int j = 0; j < modes; ++j)
      coefficients[static_cast<std::size_t>(j)] = static_cast<float>(c[j]);
    const Twist rigid = rigid_of_mode * c.cast<float>();
    build_rig(coefficients, keep_rigid ? Twist::Zero() : rigid);
    weights.setZero();  // the subject holds a neutral face while calibrating
    update_current();
  };
  int averaged = 0;
  for (int round = 0; round < options.calibration_rounds; ++round) {
    rebuild(false);
    a.setZero();
    gc.setZero();
    for (int f = 0; f < calib_count; ++f) {
      const auto fi = static_cast<std::size_t>(f);
      const Pose& p = calib_pose[fi];
      const Eigen::Vector3f pivot = p.r * centroid + p.t;
      Eigen::MatrixXd& b = b_frames[fi];
      PoseMatrix& d = d_frames[fi];
      PoseVector& gp = g_frames[fi];
      b.setZero();
      d.setZero();
      gp.setZero();
      // A residual r with identity row rd and pose row jp, weight w, into the normal equations.
      auto add_row = [&](const Eigen::VectorXd& rd, const PoseVector& jp, auto r, float w) {
        a.selfadjointView<Eigen::Lower>().rankUpdate(rd, w);
        gc += (w * r) * rd;
        b.noalias() += (w * rd) * jp.transpose();
        d.noalias() += w * jp * jp.transpose();
        gp += (w * r) * jp;
      };
      for (int i = 0; i < n; ++i) {
        Eigen::Vector3f x, nn, q;
        if (!facing_sample(p, i, x, nn)) continue;
        if (!measured_point(calib_depth[fi], calib_box[fi], x, q)) continue;
        const Eigen::Vector3f& nm = normals[static_cast<std::size_t>(i)];
        const float r = nn.dot(x - q);
        const float w = tukey(r, options.icp_gate_mm);
        if (w <= 0.0f) continue;
        // d r / d c = n_camera . R U_i = n_model . U_i; d r / d (omega, t) as in icp().
        row = nm.x() * identity_at_samples.row(3 * i) +
              nm.y() * identity_at_samples.row(3 * i + 1) +
              nm.z() * identity_at_samples.row(3 * i + 2);
        PoseVector jp;
        jp.head<3>() = (x - pivot).cross(nn).cast<double>();
        jp.tail<3>() = nn.cast<double>();
        add_row(row.cast<double>(), jp, r, w);
      }
      // Landmark rows: the reprojection error r = proj(R m_l(c) + t) - detected of each interior
      // landmark, per image axis a with v_a the row of d proj / d x (model frame): d r_a / d c =
      // v_a . dm_l/dc, where dm_l/dc is the mode minus its rigid part (rebuild(false)),
      // omega x (mean_l - pivot) + t; d r_a / d (omega, t) = ((x - pivot) x v_a, v_a) (camera).
      // Depth sees a lip or a lid slide along the face hardly at all; the landmarks do.
      const float lw = options.calibration_landmark_weight * calib_landmark_scale[fi];
      for (int l = 17; l < 68 && lw > 0.0f; ++l) {
        const std::size_t at = fi * 68 + static_cast<std::size_t>(l);
        if (!calib_landmark_valid[at]) continue;
        const Eigen::Vector3f x = landmark_in_camera(p, l);
        if (x.z() <= 1.0f) continue;
        const Eigen::Vector2f res = pixel_of(x) - calib_landmarks[at];
        const float rn = res.norm();
        const float w =
            lw * (rn < options.landmark_huber_px ? 1.0f : options.landmark_huber_px / rn);
        const Eigen::Matrix<float, 2, 3> jproj = projection_jacobian(x);
        const Eigen::Matrix<float, 2, 3> jmodel = jproj * p.r;
        const auto mv = model->landmark_vertices[static_cast<std::size_t>(l)];
        const Eigen::Vector3f y =
            Eigen::Vector3f(model->neutral[3 * mv], model->neutral[3 * mv + 1],
                            model->neutral[3 * mv + 2]) -
            rigid_pivot;
        for (int ax = 0; ax < 2; ++ax) {
          const Eigen::Vector3f vm = jmodel.row(ax).transpose();
          row = vm.x() * identity_at_landmarks.row(3 * l) +
                vm.y() * identity_at_landmarks.row(3 * l + 1) +
                vm.z() * identity_at_landmarks.row(3 * l + 2);
          row.noalias() -= rigid_of_mode.topRows<3>().transpose() * y.cross(vm);
          row.noalias() -= rigid_of_mode.bottomRows<3>().transpose() * vm;
          const Eigen::Vector3f vc = jproj.row(ax).transpose();
          PoseVector jp;
          jp.head<3>() = (x - pivot).cross(vc).cast<double>();
          jp.tail<3>() = vc.cast<double>();
          add_row(row.cast<double>(), jp, static_cast<double>(res[ax]), w);
        }
      }
    }
    schur = a.selfadjointView<Eigen::Lower>();
    schur.diagonal().array() += options.identity_prior;
    rhs = -(gc + options.identity_prior * c);
    for (int f = 0; f < calib_count; ++f) {
      const auto fi = static_cast<std::size_t>(f);
      d_frames[fi].diagonal().array() += 1e-3;
      d_solvers[fi].compute(d_frames[fi]);
      bd = d_solvers[fi].solve(b_frames[fi].transpose()).transpose();  // B_f D_f^-1
      schur.noalias() -= bd * b_frames[fi].transpose();
      rhs.noalias() += bd * g_frames[fi];
    }
    const Eigen::VectorXd dc = schur.ldlt().solve(rhs);
    c += dc;
    for (int f = 0; f < calib_count; ++f) {
      const auto fi = static_cast<std::size_t>(f);
      const PoseVector xi = d_solvers[fi].solve(-(g_frames[fi] + b_frames[fi].transpose() * dc));
      Pose& p = calib_pose[fi];
      p.apply_twist(xi.head<3>().cast<float>(), xi.tail<3>().cast<float>(), p.r * centroid + p.t);
      p.r = Eigen::Quaternionf(p.r).normalized().toRotationMatrix();
    }
    if (2 * round >= options.calibration_rounds) {
      c_sum += c;
      ++averaged;
    }
  }
  if (averaged > 0) c = c_sum / averaged;
  // The final face keeps the identity's rigid part when asked (keep_identity_rigid): the PCA
  // modes tie it to their shape, so the fitted shape predicts it, and the face's frame then
  // stays the model's (absolute pose) instead of moving by the removed motion. The stored
  // frames are re-tracked with it.
  rebuild(options.keep_identity_rigid);
  float rms_sum = 0.0f;
  for (int f = 0; f < calib_count; ++f) {
    rms_sum += icp(calib_depth[static_cast<std::size_t>(f)], calib_box[static_cast<std::size_t>(f)],
                   calib_pose[static_cast<std::size_t>(f)], options.icp_iterations,
                   options.icp_gate_mm, options.icp_gate_mm)
                   .rms;
  }
  if (options.calibrate_depth_offsets) calibrate_depth_offsets();
  if (options.calibrate_landmark_offsets) calibrate_landmark_offsets();
  // Continue from the last calibration frame.
  pose = calib_pose[static_cast<std::size_t>(calib_count - 1)];
  weights.setZero();
  previous_weights = weights;
  update_current();
  calibrated = true;
  return rms_sum / static_cast<float>(calib_count);
}

void FaceTracker::State::calibrate_landmark_offsets() {
  // Mean over the calibration frames (neutral face, final poses) of the detected point's ray at
  // the model landmark's depth minus the model landmark, rotated into the model frame:
  //   d_l = mean_f R_f^T ([(u - cx) z / fx, (v - cy) z / fy, z] - x),  x = R_f m_l + t_f.
  // The identity fit sees depth only, so a detector's consistent placement on this face (and
  // the identity's error at the landmark vertices) would otherwise pull the expression weights
  // on every frame. Points seen on fewer than half the frames, or further off than
  // max_landmark_offset_mm, keep no offset.
  landmark_base -= landmark_offset;  // the model's landmark vertices on this face
  landmark_offset.setZero();
  weights.setZero();
  update_current();
  for (int l = 17; l < 68; ++l) {
    Eigen::Vector3f sum = Eigen::Vector3f::Zero();
    int seen = 0;
    for (int f = 0; f < calib_count; ++f) {
      const std::size_t at = static_cast<std::size_t>(f) * 68 + static_cast<std::size_t>(l);
      if (!calib_landmark_valid[at]) continue;
      const Pose& p = calib_pose[static_cast<std::size_t>(f)];
      const Eigen::Vector3f x = landmark_in_camera(p, l);
      if (x.z() <= 1.0f) continue;
      const Eigen::Vector2f& px = calib_landmarks[at];
      const Eigen::Vector3f ray((px.x() - cx) * x.z() / fx, (px.y() - cy) * x.z() / fy, x.z());
      sum += p.r.transpose() * (ray - x);
      ++seen;
    }
    if (2 * seen < calib_count || seen == 0) continue;
    const Eigen::Vector3f d = sum / static_cast<float>(seen);
    if (d.norm() <= options.max_landmark_offset_mm) landmark_offset.segment<3>(3 * l) = d;
  }
  landmark_base += landmark_offset;
  update_current();
}

void FaceTracker::State::calibrate_depth_offsets() {
  // o_i = mean_f n_i . (q_f - x_f) over the frames where sample i has an inlier depth (model
  // frame, neutral face, final calibration poses); base_i += o_i n_i. Per sample: what the
  // identity fit misses that moved the weights was fine-scale (take 1002: averaging the offsets
  // over 8 mm lost it, and the browDown_R stand-in came back).
  weights.setZero();
  update_current();
  std::fill(found_residual.begin(), found_residual.end(), 0.0f);  // sum of residuals
  std::fill(found_sample.begin(), found_sample.end(), 0);         // frames seen
  for (int f = 0; f < calib_count; ++f) {
    const auto fi = static_cast<std::size_t>(f);
    const Pose& p = calib_pose[fi];
    const Eigen::Matrix3f rt = p.r.transpose();
    for (int i = 0; i < n; ++i) {
      Eigen::Vector3f x, nn, measured;
      if (!facing_sample(p, i, x, nn)) continue;
      if (!measured_point(calib_depth[fi], calib_box[fi], x, measured)) continue;
      const Eigen::Vector3f q = rt * (measured - p.t);
      const float r = normals[static_cast<std::size_t>(i)].dot(q - sample(i));
      if (std::abs(r) > options.icp_gate_mm) continue;
      found_residual[static_cast<std::size_t>(i)] += r;
      ++found_sample[static_cast<std::size_t>(i)];
    }
  }
  for (int i = 0; i < n; ++i) {
    const auto ii = static_cast<std::size_t>(i);
    if (found_sample[ii] == 0 || 2 * found_sample[ii] < calib_count) continue;
    const float o = std::clamp(found_residual[ii] / static_cast<float>(found_sample[ii]),
                               -options.max_depth_offset_mm, options.max_depth_offset_mm);
    base.segment<3>(3 * i) += o * normals[ii];
  }
  update_current();
}

}  // namespace fb
