// facebooth-lab eval track: a tracked take scored against its ground truth.
#include <Eigen/Geometry>
#include <algorithm>
#include <functional>

#include "sim/lab/track_eval_parts.hpp"

namespace fb::cli::track_eval {

// The rigid motion between two identities' neutral faces (model frame), least squares over the
// front-facing face vertices: how far the calibrated face's frame sits from the true one. Depth
// of the front of the face cannot tell this apart from a head pose (the gauge of the absolute
// pose), so it predicts the constant offset between estimated and true poses.
// `estimate` is in `estimate_model`'s identity modes (the face model's or a bilinear model's).
std::pair<double, double> identity_rigid_offset(const FaceModel& model,
                                                std::span<const float> truth,
                                                const FaceModel& estimate_model,
                                                std::span<const float> estimate,
                                                const Eigen::Vector3d& centre) {
  std::vector<float> a(static_cast<std::size_t>(3 * model.vertex_count)), b(a.size());
  model.evaluate(truth, {}, a);
  estimate_model.evaluate(estimate, {}, b);
  std::vector<std::uint32_t> vertices;
  for (auto v : model.fitting_vertices) {
    if (static_cast<int>(v) < model.face_vertex_count && model.neutral[3 * v + 2] > 0.0f)
      vertices.push_back(v);
  }
  Eigen::Matrix3Xd src(3, vertices.size()), dst(3, vertices.size());
  for (std::size_t i = 0; i < vertices.size(); ++i) {
    const auto v = vertices[i];
    src.col(static_cast<Eigen::Index>(i)) = Eigen::Vector3d(a[3 * v], a[3 * v + 1], a[3 * v + 2]);
    dst.col(static_cast<Eigen::Index>(i)) = Eigen::Vector3d(b[3 * v], b[3 * v + 1], b[3 * v + 2]);
  }
  const Eigen::Matrix4d t = Eigen::umeyama(src, dst, false);
  const Eigen::Matrix3d r = t.topLeftCorner<3, 3>();
  const double angle = Eigen::AngleAxisd(r).angle() * kDeg;
  const double shift = (r * centre + t.topRightCorner<3, 1>() - centre).norm();
  return {angle, shift};
}

// The calibrated face's model frame differs from the true one by a constant rigid motion
// (the part of the identity that looks like a head rotation/translation, which depth of the
// front of the face cannot separate from the pose): Q = mean over tracked frames of
// T_true^-1 T_est. Pose errors are scored after it (gauge-free); absolute ones are reported too.
RigidPose calibration_gauge(const std::vector<FrameResult>& results) {
  Eigen::Vector4d qsum = Eigen::Vector4d::Zero();
  Eigen::Vector3d tsum = Eigen::Vector3d::Zero();
  int qn = 0;
  for (const auto& r : results) {
    if (!r.calibrated || r.state == TrackState::kCalibrating || !tracked(r.state)) continue;
    const RigidPose d = compose(r.truth.inverse(), r.estimate);
    Eigen::Vector4d q = d.rotation.coeffs();
    if (qn > 0 && q.dot(qsum) < 0) q = -q;
    qsum += q;
    tsum += d.translation;
    ++qn;
  }
  RigidPose gauge;
  if (qn > 0) {
    gauge.rotation.coeffs() = qsum.normalized();
    gauge.translation = tsum / qn;
  }
  return gauge;
}

void score(const RenderedTake& take, const std::vector<FrameResult>& results, Score& s, int k) {
  if (s.per_shape_sum.empty()) s.per_shape_sum.assign(static_cast<std::size_t>(k), 0.0);
  const RigidPose gauge = calibration_gauge(results);
  for (const auto& r : results) {
    if (!r.calibrated || r.state == TrackState::kCalibrating) continue;
    ++s.frames;
    if (!tracked(r.state)) ++s.lost;
    double sum = 0;
    for (int j = 0; j < k; ++j) {
      sum += r.abs_error[static_cast<std::size_t>(j)];
      s.per_shape_sum[static_cast<std::size_t>(j)] += r.abs_error[static_cast<std::size_t>(j)];
    }
    s.weight_error.push_back(sum / k);
    double active = 0;
    for (int j : take.take.active) active += r.abs_error[static_cast<std::size_t>(j)];
    s.active_error.push_back(active / std::max<std::size_t>(1, take.take.active.size()));
    const RigidPose aligned = compose(r.truth, gauge);
    const Eigen::Vector3d c = take.take.face_centre_model;
    s.rot.push_back(rotation_error_deg(r.estimate, aligned));
    s.centre.push_back((r.estimate.apply(c) - aligned.apply(c)).norm());
    s.abs_rot.push_back(r.rotation_error_deg);
    s.abs_centre.push_back(r.centre_error_mm);
    s.origin.push_back(r.origin_error_mm);
    s.raw_rot.push_back(r.raw_rotation_error_deg);
    s.raw_centre.push_back(r.raw_centre_error_mm);
  }
}

nlohmann::json score_json(const Score& s, const FaceModel& model) {
  nlohmann::json j;
  j["frames_scored"] = s.frames;
  j["frames_lost"] = s.lost;
  j["weight_mae"] = stats_of(s.weight_error).mean;
  j["weight_mae_active_shapes"] = stats_of(s.active_error).mean;
  j["pose_error_deg"] = stats_of(s.rot).mean;
  j["pose_error_mm"] = stats_of(s.centre).mean;
  j["pose_error_deg_stats"] = to_json(stats_of(s.rot));
  j["pose_error_mm_stats"] = to_json(stats_of(s.centre));
  j["absolute_pose_error_deg"] = stats_of(s.abs_rot).mean;
  j["absolute_pose_error_mm"] = stats_of(s.abs_centre).mean;
  j["origin_error_mm_stats"] = to_json(stats_of(s.origin));
  j["raw_pose_error_deg"] = stats_of(s.raw_rot).mean;
  j["raw_pose_error_mm"] = stats_of(s.raw_centre).mean;
  nlohmann::json per_shape;
  for (std::size_t i = 0; i < s.per_shape_sum.size(); ++i) {
    per_shape[model.expression_names[i]] = s.frames ? s.per_shape_sum[i] / s.frames : 0.0;
  }
  j["per_shape_mae"] = per_shape;
  return j;
}

// The n shapes of a per-shape figure with the largest values, largest first.
nlohmann::json top_shapes(const nlohmann::json& per_shape, std::size_t n) {
  std::vector<std::pair<double, std::string>> v;
  for (const auto& [name, value] : per_shape.items()) v.emplace_back(value.get<double>(), name);
  std::sort(v.begin(), v.end(), std::greater<>());
  nlohmann::json out = nlohmann::json::object();
  for (std::size_t i = 0; i < v.size() && i < n; ++i) out[v[i].second] = v[i].first;
  return out;
}

}  // namespace fb::cli::track_eval
