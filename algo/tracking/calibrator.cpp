#include "algo/tracking/calibrator.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include "algo/tracking/occlusion_mask.hpp"

namespace fb {

using PoseMatrix = Eigen::Matrix<double, 6, 6>;
using PoseVector = Eigen::Matrix<double, 6, 1>;

// The joint identity + pose normal equations of one Gauss-Newton round: A, g_c over the
// identity, B_f, D_f, g_f per frame.
struct Calibrator::NormalEquations {
  NormalEquations(int modes, int frames)
      : a(modes, modes),
        schur(modes, modes),
        bd(modes, 6),
        gc(modes),
        rhs(modes),
        b_frames(static_cast<std::size_t>(frames), Eigen::MatrixXd(modes, 6)),
        d_frames(static_cast<std::size_t>(frames)),
        d_solvers(static_cast<std::size_t>(frames)),
        g_frames(static_cast<std::size_t>(frames)),
        row(modes) {}
  Eigen::MatrixXd a, schur, bd;
  Eigen::VectorXd gc, rhs;
  std::vector<Eigen::MatrixXd> b_frames;
  std::vector<PoseMatrix> d_frames;
  std::vector<Eigen::LDLT<PoseMatrix>> d_solvers;
  std::vector<PoseVector> g_frames;
  Eigen::VectorXf row;  // scratch: one identity row
};

void Calibrator::allocate(const CalibratorOptions& options, const TrackerCamera& camera,
                          float landmark_huber_px, float landmark_noise_px, int n) {
  options_ = options;
  camera_ = camera;
  landmark_huber_px_ = landmark_huber_px;
  landmark_noise_px_ = landmark_noise_px;
  const auto frames = static_cast<std::size_t>(options.calibration_frames);
  depth_.resize(frames);
  for (auto& f : depth_) f.resize(camera.width, camera.height);
  box_.resize(frames);
  landmarks_.assign(frames * 68, Eigen::Vector2f::Zero());
  landmark_valid_.assign(frames * 68, 0);
  landmark_scale_.assign(frames, 1.0f);
  pose_.resize(frames);
  offset_sum_.resize(static_cast<std::size_t>(n));
  offset_seen_.resize(static_cast<std::size_t>(n));
}

void Calibrator::add_frame(const Image<float>& smoothed, const PixelRect& box,
                           const RigidPoseF& pose, const TrackLandmarks* landmarks) {
  const auto f = static_cast<std::size_t>(count_);
  std::copy(smoothed.pixels.begin(), smoothed.pixels.end(), depth_[f].pixels.begin());
  box_[f] = box;
  pose_[f] = pose;
  const bool have_landmarks = landmarks != nullptr && landmarks->points.size() >= 68;
  landmark_scale_[f] = have_landmarks ? landmark_scale(*landmarks, landmark_noise_px_) : 1.0f;
  for (std::size_t l = 0; l < 68; ++l) {
    const bool valid = have_landmarks && (landmarks->valid.empty() || landmarks->valid[l] != 0);
    landmark_valid_[f * 68 + l] = valid ? 1 : 0;
    if (valid) landmarks_[f * 68 + l] = landmarks->points[l];
  }
  ++count_;
}

float Calibrator::calibrate(SubjectRig& rig, const RigidIcp& icp, ShapeVector& weights) {
  gate_mm_ = icp.options().icp_gate_mm;
  Eigen::VectorXd c = Eigen::VectorXd::Zero(rig.modes);
  for (int j = 0; j < rig.modes && j < static_cast<int>(rig.identity.size()); ++j)
    c[j] = rig.identity[static_cast<std::size_t>(j)];
  fit_identity(rig, weights, c);
  // The final face keeps the identity's rigid part when asked (keep_identity_rigid): the PCA
  // modes tie it to their shape, so the fitted shape predicts it, and the face's frame then
  // stays the model's (absolute pose) instead of moving by the removed motion. The stored
  // frames are re-tracked with it.
  std::vector<float> coefficients(static_cast<std::size_t>(rig.modes));
  for (int j = 0; j < rig.modes; ++j)
    coefficients[static_cast<std::size_t>(j)] = static_cast<float>(c[j]);
  const SubjectRig::Twist rigid = rig.rigid_of_mode * c.cast<float>();
  rig.build(coefficients, weights,
            options_.keep_identity_rigid ? SubjectRig::Twist::Zero() : rigid);
  weights.setZero();  // the subject holds a neutral face while calibrating
  rig.update_current(weights);
  rig.build_subject_blendshapes(weights);
  const OcclusionMask no_mask;  // the stored frames: not the current frame's mask
  const RigidIcpOptions& io = icp.options();
  float rms_sum = 0.0f;
  for (int f = 0; f < count_; ++f) {
    const auto fi = static_cast<std::size_t>(f);
    rms_sum += icp.run(rig, camera_, no_mask, depth_[fi], box_[fi], pose_[fi], io.icp_iterations,
                       io.icp_gate_mm, io.icp_gate_mm)
                   .rms;
  }
  if (options_.calibrate_depth_offsets) depth_offsets(rig, weights);
  if (options_.calibrate_landmark_offsets) landmark_offsets(rig, weights);
  weights.setZero();
  rig.update_current(weights);
  return rms_sum / static_cast<float>(count_);
}

void Calibrator::fit_identity(SubjectRig& rig, ShapeVector& weights, Eigen::VectorXd& c) {
  // Identity and the calibration frames' poses by joint Gauss-Newton on the point-to-plane
  // residuals of all stored frames, r = n . (x - q) with x = R_f (neutral_i + U_i c) + t_f,
  // and a Tikhonov prior on c (coefficients are in sigma units). The unknowns are c (m) and a
  // twist per frame (6); the poses are eliminated by their Schur complement:
  //   (A + lambda I - sum_f B_f D_f^-1 B_f^T) dc = -(g_c + lambda c) + sum_f B_f D_f^-1 g_f,
  //   dp_f = -D_f^-1 (g_f + B_f^T dc),
  // A = sum w J_c J_c^T, B_f = sum w J_c J_p^T, D_f = sum w J_p J_p^T over frame f's rows.
  // Alternating the two blocks instead converged slowly along the directions where a change
  // of shape and a head rotation look alike, and stopped degrees short when the mean face
  // started a few degrees off. The projective association moves with every step, so the
  // iterates end up circling the minimum (|dc| ~ 0.4 sigma); the identity is their mean over
  // the second half of the rounds.
  const int modes = rig.modes;
  NormalEquations e(modes, count_);
  Eigen::VectorXd c_sum = Eigen::VectorXd::Zero(modes);
  std::vector<float> coefficients(static_cast<std::size_t>(modes));
  int averaged = 0;
  for (int round = 0; round < options_.calibration_rounds; ++round) {
    // The rig of the current coefficients without their rigid part.
    for (int j = 0; j < modes; ++j)
      coefficients[static_cast<std::size_t>(j)] = static_cast<float>(c[j]);
    const SubjectRig::Twist rigid = rig.rigid_of_mode * c.cast<float>();
    rig.build(coefficients, weights, rigid);
    weights.setZero();  // the subject holds a neutral face while calibrating
    rig.update_current(weights);
    e.a.setZero();
    e.gc.setZero();
    for (int f = 0; f < count_; ++f) add_frame_rows(rig, f, e);
    e.schur = e.a.selfadjointView<Eigen::Lower>();
    e.schur.diagonal().array() += options_.identity_prior;
    e.rhs = -(e.gc + options_.identity_prior * c);
    for (int f = 0; f < count_; ++f) {
      const auto fi = static_cast<std::size_t>(f);
      e.d_frames[fi].diagonal().array() += 1e-3;
      e.d_solvers[fi].compute(e.d_frames[fi]);
      e.bd = e.d_solvers[fi].solve(e.b_frames[fi].transpose()).transpose();  // B_f D_f^-1
      e.schur.noalias() -= e.bd * e.b_frames[fi].transpose();
      e.rhs.noalias() += e.bd * e.g_frames[fi];
    }
    const Eigen::VectorXd dc = e.schur.ldlt().solve(e.rhs);
    c += dc;
    for (int f = 0; f < count_; ++f) {
      const auto fi = static_cast<std::size_t>(f);
      const PoseVector xi =
          e.d_solvers[fi].solve(-(e.g_frames[fi] + e.b_frames[fi].transpose() * dc));
      RigidPoseF& p = pose_[fi];
      p.apply_twist(xi.head<3>().cast<float>(), xi.tail<3>().cast<float>(),
                    p.r * rig.centroid + p.t);
      p.r = Eigen::Quaternionf(p.r).normalized().toRotationMatrix();
    }
    if (2 * round >= options_.calibration_rounds) {
      c_sum += c;
      ++averaged;
    }
  }
  if (averaged > 0) c = c_sum / averaged;
}

void Calibrator::add_frame_rows(const SubjectRig& rig, int f, NormalEquations& e) const {
  const auto fi = static_cast<std::size_t>(f);
  const RigidPoseF& p = pose_[fi];
  const Eigen::Vector3f pivot = p.r * rig.centroid + p.t;
  Eigen::MatrixXd& b = e.b_frames[fi];
  PoseMatrix& d = e.d_frames[fi];
  PoseVector& gp = e.g_frames[fi];
  Eigen::VectorXf& row = e.row;
  b.setZero();
  d.setZero();
  gp.setZero();
  // A residual r with identity row rd and pose row jp, weight w, into the normal equations.
  auto add_row = [&](const Eigen::VectorXd& rd, const PoseVector& jp, auto r, float w) {
    e.a.selfadjointView<Eigen::Lower>().rankUpdate(rd, w);
    e.gc += (w * r) * rd;
    b.noalias() += (w * rd) * jp.transpose();
    d.noalias() += w * jp * jp.transpose();
    gp += (w * r) * jp;
  };
  for (int i = 0; i < rig.n; ++i) {
    Eigen::Vector3f x, nn, q;
    if (!rig.facing_sample(p, i, x, nn)) continue;
    if (!camera_.measured_point(depth_[fi], box_[fi], x, q)) continue;
    const Eigen::Vector3f& nm = rig.normals[static_cast<std::size_t>(i)];
    const float r = nn.dot(x - q);
    const float w = tukey(r, gate_mm_);
    if (w <= 0.0f) continue;
    // d r / d c = n_camera . R U_i = n_model . U_i; d r / d (omega, t) as in RigidIcp.
    row = nm.x() * rig.identity_at_samples.row(3 * i) +
          nm.y() * rig.identity_at_samples.row(3 * i + 1) +
          nm.z() * rig.identity_at_samples.row(3 * i + 2);
    PoseVector jp;
    jp.head<3>() = (x - pivot).cross(nn).cast<double>();
    jp.tail<3>() = nn.cast<double>();
    add_row(row.cast<double>(), jp, r, w);
  }
  // Landmark rows: the reprojection error r = proj(R m_l(c) + t) - detected of each interior
  // landmark, per image axis a with v_a the row of d proj / d x (model frame): d r_a / d c =
  // v_a . dm_l/dc, where dm_l/dc is the mode minus its rigid part,
  // omega x (mean_l - pivot) + t; d r_a / d (omega, t) = ((x - pivot) x v_a, v_a) (camera).
  // Depth sees a lip or a lid slide along the face hardly at all; the landmarks do.
  const FaceModel& model = *rig.model;
  const float lw = options_.calibration_landmark_weight * landmark_scale_[fi];
  for (int l = 17; l < 68 && lw > 0.0f; ++l) {
    const std::size_t at = fi * 68 + static_cast<std::size_t>(l);
    if (!landmark_valid_[at]) continue;
    const Eigen::Vector3f x = rig.landmark_in_camera(p, l);
    if (x.z() <= 1.0f) continue;
    const Eigen::Vector2f res = camera_.pixel_of(x) - landmarks_[at];
    const float rn = res.norm();
    const float w = lw * (rn < landmark_huber_px_ ? 1.0f : landmark_huber_px_ / rn);
    const Eigen::Matrix<float, 2, 3> jproj = camera_.projection_jacobian(x);
    const Eigen::Matrix<float, 2, 3> jmodel = jproj * p.r;
    const auto mv = model.landmark_vertices[static_cast<std::size_t>(l)];
    const Eigen::Vector3f y = Eigen::Vector3f(model.neutral[3 * mv], model.neutral[3 * mv + 1],
                                              model.neutral[3 * mv + 2]) -
                              rig.rigid_pivot;
    for (int ax = 0; ax < 2; ++ax) {
      const Eigen::Vector3f vm = jmodel.row(ax).transpose();
      row = vm.x() * rig.identity_at_landmarks.row(3 * l) +
            vm.y() * rig.identity_at_landmarks.row(3 * l + 1) +
            vm.z() * rig.identity_at_landmarks.row(3 * l + 2);
      row.noalias() -= rig.rigid_of_mode.topRows<3>().transpose() * y.cross(vm);
      row.noalias() -= rig.rigid_of_mode.bottomRows<3>().transpose() * vm;
      const Eigen::Vector3f vc = jproj.row(ax).transpose();
      PoseVector jp;
      jp.head<3>() = (x - pivot).cross(vc).cast<double>();
      jp.tail<3>() = vc.cast<double>();
      add_row(row.cast<double>(), jp, static_cast<double>(res[ax]), w);
    }
  }
}

void Calibrator::landmark_offsets(SubjectRig& rig, ShapeVector& weights) const {
  // Mean over the calibration frames (neutral face, final poses) of the detected point's ray at
  // the model landmark's depth minus the model landmark, rotated into the model frame:
  //   d_l = mean_f R_f^T ([(u - cx) z / fx, (v - cy) z / fy, z] - x),  x = R_f m_l + t_f.
  // The identity fit sees depth only, so a detector's consistent placement on this face (and
  // the identity's error at the landmark vertices) would otherwise pull the expression weights
  // on every frame. Points seen on fewer than half the frames, or further off than
  // max_landmark_offset_mm, keep no offset.
  rig.landmark_base -= rig.landmark_offset;  // the model's landmark vertices on this face
  rig.landmark_offset.setZero();
  weights.setZero();
  rig.update_current(weights);
  for (int l = 17; l < 68; ++l) {
    Eigen::Vector3f sum = Eigen::Vector3f::Zero();
    int seen = 0;
    for (int f = 0; f < count_; ++f) {
      const auto fi = static_cast<std::size_t>(f);
      const std::size_t at = fi * 68 + static_cast<std::size_t>(l);
      if (!landmark_valid_[at]) continue;
      const RigidPoseF& p = pose_[fi];
      const Eigen::Vector3f x = rig.landmark_in_camera(p, l);
      if (x.z() <= 1.0f) continue;
      const Eigen::Vector2f& px = landmarks_[at];
      // On the measured surface where the frame has depth there: the model's depth alone leaves
      // the offset's component along the view, which shows once the head turns.
      float z = x.z(), measured = 0.0f;
      if (options_.landmark_offset_depth_gate_mm > 0.0f &&
          camera_.depth_at(depth_[fi], box_[fi], px.x(), px.y(), measured) &&
          std::abs(measured - x.z()) <= options_.landmark_offset_depth_gate_mm)
        z = measured;
      sum += p.r.transpose() * (camera_.ray_point(px, z) - x);
      ++seen;
    }
    if (2 * seen < count_ || seen == 0) continue;
    const Eigen::Vector3f d = sum / static_cast<float>(seen);
    if (d.norm() <= options_.max_landmark_offset_mm) rig.landmark_offset.segment<3>(3 * l) = d;
  }
  rig.landmark_base += rig.landmark_offset;
  rig.update_current(weights);
}

void Calibrator::depth_offsets(SubjectRig& rig, ShapeVector& weights) {
  // o_i = mean_f n_i . (q_f - x_f) over the frames where sample i has an inlier depth (model
  // frame, neutral face, final calibration poses); base_i += o_i n_i. Per sample: what the
  // identity fit misses that moved the weights was fine-scale (averaging the offsets over 8 mm
  // lost it).
  weights.setZero();
  rig.update_current(weights);
  std::fill(offset_sum_.begin(), offset_sum_.end(), 0.0f);
  std::fill(offset_seen_.begin(), offset_seen_.end(), 0);
  for (int f = 0; f < count_; ++f) {
    const auto fi = static_cast<std::size_t>(f);
    const RigidPoseF& p = pose_[fi];
    const Eigen::Matrix3f rt = p.r.transpose();
    for (int i = 0; i < rig.n; ++i) {
      Eigen::Vector3f x, nn, measured;
      if (!rig.facing_sample(p, i, x, nn)) continue;
      if (!camera_.measured_point(depth_[fi], box_[fi], x, measured)) continue;
      const Eigen::Vector3f q = rt * (measured - p.t);
      const float r = rig.normals[static_cast<std::size_t>(i)].dot(q - rig.sample(i));
      if (std::abs(r) > gate_mm_) continue;
      offset_sum_[static_cast<std::size_t>(i)] += r;
      ++offset_seen_[static_cast<std::size_t>(i)];
    }
  }
  for (int i = 0; i < rig.n; ++i) {
    const auto ii = static_cast<std::size_t>(i);
    if (offset_seen_[ii] == 0 || 2 * offset_seen_[ii] < count_) continue;
    const float o = std::clamp(offset_sum_[ii] / static_cast<float>(offset_seen_[ii]),
                               -options_.max_depth_offset_mm, options_.max_depth_offset_mm);
    rig.base.segment<3>(3 * i) += o * rig.normals[ii];
  }
  rig.update_current(weights);
}

}  // namespace fb
