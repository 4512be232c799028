// FaceTracker: set-up (the model's rows at the samples and landmarks), the subject's rig
// (identity, stored rig), and the per-frame loop that runs the stages in the other tracker_*.cpp
// files (see face_tracker_state.hpp) and fills the report.
#include "algo/tracking/face_tracker.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <unordered_map>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include "algo/tracking/depth_filter.hpp"
#include "algo/tracking/face_tracker_state.hpp"

namespace fb {

const char* to_string(TrackState state) {
  switch (state) {
    case TrackState::kSearching:
      return "searching";
    case TrackState::kCalibrating:
      return "calibrating";
    case TrackState::kTracking:
      return "tracking";
    case TrackState::kRecovered:
      return "recovered";
    case TrackState::kLost:
      return "lost";
    case TrackState::kBadInput:
      return "bad_input";
  }
  return "unknown";
}

using namespace tracker_detail;

void FaceTracker::State::build_rig(std::span<const float> coefficients, const Twist& rigid_offset) {
  identity.assign(std::max<std::size_t>(static_cast<std::size_t>(modes), coefficients.size()),
                  0.0f);
  std::copy(coefficients.begin(), coefficients.end(), identity.begin());
  // Full-mesh neutral of this identity for the normals (area-weighted vertex normals).
  const FaceModel& m = *model;
  mesh_scratch.resize(static_cast<std::size_t>(3 * m.vertex_count));
  m.evaluate(identity, {}, mesh_scratch);
  if (!rigid_offset.isZero()) {
    // Minus the linearised rigid motion: v -= omega x (mean_v - pivot) + t.
    const Eigen::Vector3f omega = rigid_offset.head<3>(), t = rigid_offset.tail<3>();
    for (int v = 0; v < m.vertex_count; ++v) {
      const Eigen::Vector3f mean(m.neutral[3 * v], m.neutral[3 * v + 1], m.neutral[3 * v + 2]);
      const Eigen::Vector3f d = omega.cross(mean - rigid_pivot) + t;
      for (int a = 0; a < 3; ++a) mesh_scratch[3 * v + a] -= d[a];
    }
  }
  finish_rig();
}

void FaceTracker::State::finish_rig() {
  const FaceModel& m = *model;
  mesh_normals.assign(static_cast<std::size_t>(m.vertex_count), Eigen::Vector3f::Zero());
  auto vertex = [&](std::uint32_t v) {
    return Eigen::Vector3f(mesh_scratch[3 * v], mesh_scratch[3 * v + 1], mesh_scratch[3 * v + 2]);
  };
  for (std::size_t t = 0; t + 2 < m.triangles.size(); t += 3) {
    const auto a = m.triangles[t], b = m.triangles[t + 1], cc = m.triangles[t + 2];
    const Eigen::Vector3f nn = (vertex(b) - vertex(a)).cross(vertex(cc) - vertex(a));
    mesh_normals[a] += nn;
    mesh_normals[b] += nn;
    mesh_normals[cc] += nn;
  }
  base.resize(3 * n);
  normals.resize(static_cast<std::size_t>(n));
  centroid.setZero();
  nose_z = -std::numeric_limits<float>::infinity();
  for (int i = 0; i < n; ++i) {
    const auto v = sample_vertices[static_cast<std::size_t>(i)];
    base.segment<3>(3 * i) = vertex(v);
    normals[static_cast<std::size_t>(i)] = mesh_normals[v].normalized();
    centroid += vertex(v);
    nose_z = std::max(nose_z, vertex(v).z());
  }
  centroid /= static_cast<float>(n);
  // Point-to-plane rows of the weight solve: n_i . (B_i w). With the normals of the neutral
  // they do not depend on the pose (n_camera . R B_i w = n_model . B_i w).
  normal_rows.resize(n, k);
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3f& nn = normals[static_cast<std::size_t>(i)];
    normal_rows.row(i) = nn.x() * expression_at_samples.row(3 * i) +
                         nn.y() * expression_at_samples.row(3 * i + 1) +
                         nn.z() * expression_at_samples.row(3 * i + 2);
  }
  landmark_base.resize(3 * 68);
  for (int l = 0; l < 68; ++l) landmark_base.segment<3>(3 * l) = vertex(m.landmark_vertices[l]);
  landmark_base += landmark_offset;
  // Depth signal of each shape: H0_jj = sum_i (n_i . B_ij)^2. Shapes far below the median are
  // nearly invisible in depth and would wander on noise, and the gaze shapes alias the lids
  // (see TrackerOptions::hold_gaze_shapes), so they get a strong prior to 0.
  const Eigen::VectorXf signal = normal_rows.colwise().squaredNorm().transpose();
  std::vector<float> sorted(signal.data(), signal.data() + k);
  std::nth_element(sorted.begin(), sorted.begin() + k / 2, sorted.end());
  const float median = sorted[static_cast<std::size_t>(k / 2)];
  shape_ridge.resize(k);
  shape_sparsity.resize(k);
  signal_median = median;
  full_signal = signal.cwiseMax(1e-6f);
  seen_fraction = ShapeVector::Ones(k);
  weak_shapes.clear();
  for (int j = 0; j < k; ++j) {
    const bool weak = (options.hold_gaze_shapes && gaze_shape[static_cast<std::size_t>(j)]) ||
                      signal[j] < options.weak_shape_fraction * median;
    shape_ridge[j] = options.ridge + (weak ? options.weak_shape_ridge * median : 0.0f);
    if (weak) weak_shapes.push_back(j);
  }
  update_current();
}

void FaceTracker::State::output(TrackReport& report, double time_s) {
  const double dt = have_time ? time_s - last_time : 0.0;
  filtered = filter.update(pose.to_rigid(), dt);
  last_time = time_s;
  have_time = true;
  report.camera_from_model = filtered;
  report.raw_camera_from_model = pose.to_rigid();
  report.shape_count = k;
  std::fill(report.weights.begin(), report.weights.end(), 0.0f);
  for (int j = 0; j < k; ++j) report.weights[static_cast<std::size_t>(j)] = weights[j];
}

FaceTracker::FaceTracker(std::unique_ptr<State> state) : state_(std::move(state)) {}
FaceTracker::~FaceTracker() = default;

Result<std::unique_ptr<FaceTracker>> FaceTracker::create(const FaceModel& model,
                                                         const PinholeIntrinsics& intrinsics,
                                                         const TrackerOptions& options) {
  if (model.vertex_count <= 0 || model.fitting_expression_count <= 0 ||
      model.neutral.size() != static_cast<std::size_t>(3 * model.vertex_count)) {
    return fail("tracking: the face model is empty; load data/facemodel.fbfm first");
  }
  if (model.fitting_expression_count > kMaxTrackedShapes) {
    return fail("tracking: the model has " + std::to_string(model.fitting_expression_count) +
                " fitting shapes; at most " + std::to_string(kMaxTrackedShapes) + " are supported");
  }
  if (intrinsics.fx <= 0.0 || intrinsics.fy <= 0.0 || intrinsics.width <= 0 ||
      intrinsics.height <= 0) {
    return fail("tracking: the camera reports no depth intrinsics");
  }
  if (options.temporal_frames < 1 || options.temporal_frames > 16) {
    return fail("tracking: temporal_frames must be in [1, 16]");
  }
  if (options.calibration_frames < 1) return fail("tracking: calibration_frames must be >= 1");
  if (!(options.landmark_noise_px > 0.0f)) return fail("tracking: landmark_noise_px must be > 0");
  auto s = std::make_unique<State>();
  s->model = &model;
  s->options = options;
  s->intrinsics = intrinsics;
  s->fx = static_cast<float>(intrinsics.fx), s->fy = static_cast<float>(intrinsics.fy);
  s->cx = static_cast<float>(intrinsics.cx), s->cy = static_cast<float>(intrinsics.cy);
  s->width = intrinsics.width, s->height = intrinsics.height;
  s->k = model.fitting_expression_count;
  s->modes = std::clamp(options.identity_modes, 0, model.identity_count);
  s->filter = PoseFilter(options.pose_filter);
  s->gaze_shape.resize(static_cast<std::size_t>(s->k));
  for (int j = 0; j < s->k; ++j)
    s->gaze_shape[static_cast<std::size_t>(j)] =
        static_cast<std::size_t>(j) < model.expression_names.size() &&
                is_gaze_shape(model.expression_names[static_cast<std::size_t>(j)])
            ? 1
            : 0;

  // Antagonist pairs (TrackerOptions::antagonist_weight), per side.
  for (const char* side : {"_L", "_R"}) {
    constexpr std::pair<std::string_view, std::string_view> kPairs[] = {{"browDown", "browInnerUp"},
                                                                        {"browDown", "browOuterUp"},
                                                                        {"eyeWide", "eyeBlink"},
                                                                        {"eyeWide", "eyeSquint"}};
    for (const auto& [first, second] : kPairs) {
      const int a = model.expression_index(std::string(first) + side);
      const int b = model.expression_index(std::string(second) + side);
      if (a >= 0 && b >= 0 && a < s->k && b < s->k) s->antagonists.emplace_back(a, b);
    }
  }

  // --- Sample selection on the mean face: front-facing fitting vertices, one per grid cell,
  // plus the most-displaced vertices of every shape so small shapes (blinks, brows) are seen.
  const int v_count = model.vertex_count;
  std::vector<float> neutral = model.neutral;
  std::vector<Eigen::Vector3f> vn(static_cast<std::size_t>(v_count), Eigen::Vector3f::Zero());
  auto nv = [&](std::uint32_t v) {
    return Eigen::Vector3f(neutral[3 * v], neutral[3 * v + 1], neutral[3 * v + 2]);
  };
  for (std::size_t t = 0; t + 2 < model.triangles.size(); t += 3) {
    const auto a = model.triangles[t], b = model.triangles[t + 1], c = model.triangles[t + 2];
    const Eigen::Vector3f nn = (nv(b) - nv(a)).cross(nv(c) - nv(a));
    vn[a] += nn, vn[b] += nn, vn[c] += nn;
  }
  // Boundary vertices (edges of one triangle): the eye and mouth openings. Depth there sees
  // eyeballs, teeth or the mouth cavity, which the skin model does not have, so vertices within
  // `hole_margin` of them are not sampled.
  std::vector<char> boundary(static_cast<std::size_t>(v_count), 0);
  {
    std::unordered_map<long long, int> edges;
    auto key = [](std::uint32_t a, std::uint32_t b) {
      return static_cast<long long>(std::min(a, b)) * 1000003LL + std::max(a, b);
    };
    for (std::size_t t = 0; t + 2 < model.triangles.size(); t += 3) {
      for (int e = 0; e < 3; ++e)
        ++edges[key(model.triangles[t + e], model.triangles[t + (e + 1) % 3])];
    }
    for (const auto& [k, count] : edges) {
      if (count == 1) {
        boundary[static_cast<std::size_t>(k / 1000003LL)] = 1;
        boundary[static_cast<std::size_t>(k % 1000003LL)] = 1;
      }
    }
  }
  std::vector<Eigen::Vector3f> hole_points;
  for (int v = 0; v < model.face_vertex_count; ++v) {
    if (boundary[static_cast<std::size_t>(v)])
      hole_points.push_back(nv(static_cast<std::uint32_t>(v)));
  }
  std::vector<std::uint32_t> candidates;
  for (auto v : model.fitting_vertices) {
    if (static_cast<int>(v) >= model.face_vertex_count) continue;
    if (vn[v].normalized().z() < 0.25f) continue;
    bool near_hole = false;
    for (const auto& h : hole_points) {
      if ((h - nv(v)).squaredNorm() < options.hole_margin_mm * options.hole_margin_mm) {
        near_hole = true;
        break;
      }
    }
    if (!near_hole) candidates.push_back(v);
  }
  if (candidates.size() < 200) return fail("tracking: the face model has too few face vertices");
  std::unordered_map<long long, std::uint32_t> cells;
  std::vector<char> chosen(static_cast<std::size_t>(v_count), 0);
  const float spacing = std::max(1.0f, options.sample_spacing_mm);
  for (auto v : candidates) {
    const Eigen::Vector3f p = nv(v);
    const long long key = (static_cast<long long>(std::floor(p.x() / spacing)) + 100000) * 200001 +
                          static_cast<long long>(std::floor(p.y() / spacing)) + 100000;
    if (cells.emplace(key, v).second) chosen[v] = 1;
  }
  for (int j = 0; j < s->k; ++j) {
    const auto shape = model.expression_shape(j);
    std::vector<std::pair<float, std::uint32_t>> moved;
    for (auto v : candidates) {
      const float d = Eigen::Vector3f(shape[3 * v], shape[3 * v + 1], shape[3 * v + 2]).norm();
      if (d > 0.5f) moved.emplace_back(d, v);
    }
    const std::size_t take = std::min<std::size_t>(
        moved.size(), static_cast<std::size_t>(options.extra_samples_per_shape));
    std::partial_sort(moved.begin(), moved.begin() + take, moved.end(),
                      [](const auto& a, const auto& b) { return a.first > b.first; });
    for (std::size_t i = 0; i < take; ++i) chosen[moved[i].second] = 1;
  }
  for (int v = 0; v < v_count; ++v) {
    if (chosen[static_cast<std::size_t>(v)])
      s->sample_vertices.push_back(static_cast<std::uint32_t>(v));
  }
  const int n = static_cast<int>(s->sample_vertices.size());
  s->n = n;

  // --- Identity-independent bases at the samples and landmarks.
  s->expression_at_samples.resize(3 * n, s->k);
  s->identity_at_samples.resize(3 * n, s->modes);
  s->expression_at_landmarks.resize(3 * 68, s->k);
  s->identity_at_landmarks.resize(3 * 68, s->modes);
  auto fill = [&](auto& out, std::span<const std::uint32_t> vertices, bool expression) {
    const int columns = expression ? s->k : s->modes;
    for (int j = 0; j < columns; ++j) {
      const auto shape = expression ? model.expression_shape(j) : model.identity_mode(j);
      for (std::size_t i = 0; i < vertices.size(); ++i) {
        for (int a = 0; a < 3; ++a)
          out(3 * static_cast<int>(i) + a, j) = shape[3 * vertices[i] + a];
      }
    }
  };
  fill(s->expression_at_samples, s->sample_vertices, true);
  fill(s->identity_at_samples, s->sample_vertices, false);
  fill(s->expression_at_landmarks, model.landmark_vertices, true);
  fill(s->identity_at_landmarks, model.landmark_vertices, false);
  s->model_expression_at_samples = s->expression_at_samples;
  s->model_expression_at_landmarks = s->expression_at_landmarks;
  {
    // Rigid part of every identity mode at the samples: least squares against the 6 rigid
    // motions of the mean face about its sample centroid, then removed from the basis.
    Eigen::Vector3f pivot = Eigen::Vector3f::Zero();
    for (auto v : s->sample_vertices) pivot += nv(v);
    pivot /= static_cast<float>(n);
    s->rigid_pivot = pivot;
    Eigen::MatrixXd g(3 * n, 6);
    for (int i = 0; i < n; ++i) {
      const Eigen::Vector3d x =
          (nv(s->sample_vertices[static_cast<std::size_t>(i)]) - pivot).cast<double>();
      for (int a = 0; a < 3; ++a) {
        const Eigen::Vector3d e = Eigen::Vector3d::Unit(a);
        g.block<3, 1>(3 * i, a) = e.cross(x);  // rotation about axis a
        g.block<3, 1>(3 * i, 3 + a) = e;       // translation along a
      }
    }
    const Eigen::MatrixXd alpha =
        (g.transpose() * g).ldlt().solve(g.transpose() * s->identity_at_samples.cast<double>());
    s->rigid_of_mode = alpha.cast<float>();
    s->identity_at_samples -= (g * alpha).cast<float>();
  }

  // --- Buffers at their final size.
  s->weights = ShapeVector::Zero(s->k);
  s->previous_weights = ShapeVector::Zero(s->k);
  s->h.resize(s->k, s->k);
  s->h_hidden.resize(s->k, s->k);
  s->g.resize(s->k);
  s->rows.resize(n + 2 * 68, s->k);
  s->targets.resize(n + 2 * 68);
  s->found_sample.resize(static_cast<std::size_t>(n));
  s->found_residual.resize(static_cast<std::size_t>(n));
  s->found_target.resize(static_cast<std::size_t>(n));
  s->abs_scratch.resize(static_cast<std::size_t>(n));
  s->occluded.assign(static_cast<std::size_t>(n), 0);
  s->current.resize(3 * n);
  s->landmark_current.resize(3 * 68);
  s->ring.resize(static_cast<std::size_t>(options.temporal_frames));
  for (auto& f : s->ring) f.resize(s->width, s->height);
  s->smoothed.resize(s->width, s->height);
  s->spatial_scratch.resize(s->width, s->height);
  s->calib_depth.resize(static_cast<std::size_t>(options.calibration_frames));
  for (auto& f : s->calib_depth) f.resize(s->width, s->height);
  s->calib_box.resize(static_cast<std::size_t>(options.calibration_frames));
  s->calib_landmarks.assign(static_cast<std::size_t>(options.calibration_frames) * 68,
                            Eigen::Vector2f::Zero());
  s->calib_landmark_valid.assign(static_cast<std::size_t>(options.calibration_frames) * 68, 0);
  s->calib_landmark_scale.assign(static_cast<std::size_t>(options.calibration_frames), 1.0f);
  s->landmark_offset = Eigen::VectorXf::Zero(3 * 68);
  s->calib_pose.resize(static_cast<std::size_t>(options.calibration_frames));
  s->calib_weights.assign(static_cast<std::size_t>(options.calibration_frames),
                          ShapeVector::Zero(s->k));
  s->build_rig({});
  return std::unique_ptr<FaceTracker>(new FaceTracker(std::move(s)));
}

Result<void> FaceTracker::set_identity(std::span<const float> coefficients) {
  State& s = *state_;
  if (coefficients.size() > static_cast<std::size_t>(s.model->identity_count)) {
    return fail("tracking: " + std::to_string(coefficients.size()) +
                " identity coefficients given, the model has " +
                std::to_string(s.model->identity_count));
  }
  s.use_model_expressions();
  s.landmark_offset.setZero();  // measured by calibration only
  s.build_rig(coefficients);
  s.calibrated = true;
  s.calib_count = 0;
  return success();
}

Result<void> FaceTracker::set_rig(const TrackerRig& rig) {
  State& s = *state_;
  const FaceModel& m = *s.model;
  const std::size_t size = static_cast<std::size_t>(3 * m.vertex_count);
  if (rig.neutral.size() != size) {
    return fail("tracking: the rig's neutral has " + std::to_string(rig.neutral.size() / 3) +
                " vertices, the face model " + std::to_string(m.vertex_count) +
                "; only rigs in the face model's topology can be tracked");
  }
  for (const auto& [index, shape] : rig.shapes) {
    if (index < 0 || index >= s.k) {
      return fail("tracking: rig shape index " + std::to_string(index) +
                  " is not one of the model's " + std::to_string(s.k) + " fitting shapes");
    }
    if (shape.size() != size) {
      return fail("tracking: rig shape '" + m.expression_names[static_cast<std::size_t>(index)] +
                  "' does not have the neutral's vertex count");
    }
  }
  s.expression_at_samples = s.model_expression_at_samples;
  s.expression_at_landmarks = s.model_expression_at_landmarks;
  auto replace = [&](auto& out, std::span<const std::uint32_t> vertices, int j,
                     std::span<const float> shape) {
    for (std::size_t i = 0; i < vertices.size(); ++i) {
      for (int a = 0; a < 3; ++a) {
        const std::size_t c = 3 * vertices[i] + static_cast<std::size_t>(a);
        out(3 * static_cast<int>(i) + a, j) = shape[c] - rig.neutral[c];
      }
    }
  };
  for (const auto& [index, shape] : rig.shapes) {
    replace(s.expression_at_samples, s.sample_vertices, index, shape);
    replace(s.expression_at_landmarks, m.landmark_vertices, index, shape);
  }
  s.custom_rig = true;
  s.identity.assign(static_cast<std::size_t>(s.modes), 0.0f);
  s.mesh_scratch.assign(rig.neutral.begin(), rig.neutral.end());
  s.landmark_offset.setZero();
  s.finish_rig();
  s.calibrated = true;
  s.calib_count = 0;
  return success();
}

void FaceTracker::reset() {
  State& s = *state_;
  s.calibrated = false;
  s.calib_count = 0;
  s.have_pose = s.have_last_good = s.lost = s.have_time = false;
  s.ring_count = 0;
  s.weights.setZero();
  s.previous_weights.setZero();
  s.filter.reset();
  s.landmark_offset.setZero();
  s.use_model_expressions();
  s.build_rig({});
}

bool FaceTracker::calibrated() const {
  return state_->calibrated;
}
std::span<const float> FaceTracker::identity() const {
  return state_->identity;
}
int FaceTracker::sample_count() const {
  return state_->n;
}
int FaceTracker::shape_count() const {
  return state_->k;
}
std::span<const int> FaceTracker::weak_shapes() const {
  return state_->weak_shapes;
}
std::span<const std::string> FaceTracker::shape_names() const {
  return std::span<const std::string>(state_->model->expression_names)
      .first(static_cast<std::size_t>(state_->k));
}

void FaceTracker::track(const DepthImage& depth, double time_s, const TrackLandmarks* landmarks,
                        TrackReport& report) {
  State& s = *state_;
  report.times = {};
  report.face_found = false;
  report.loss_reason = "";
  report.samples_used = report.inliers = report.landmarks_used = 0;
  report.rms_mm = 0.0f;
  report.calibration_frames_left = s.calibrated ? 0 : s.options.calibration_frames - s.calib_count;
  auto keep_last = [&](TrackState state, const char* reason) {
    report.state = state;
    report.loss_reason = reason;
    report.camera_from_model = s.filtered;
    report.raw_camera_from_model = s.pose.to_rigid();
    report.shape_count = s.k;
    for (int j = 0; j < s.k; ++j)
      report.weights[static_cast<std::size_t>(j)] = s.previous_weights[j];
  };
  if (depth.width != s.width || depth.height != s.height ||
      depth.pixels.size() != static_cast<std::size_t>(s.width) * s.height) {
    keep_last(TrackState::kBadInput, "depth frame size does not match the camera intrinsics");
    return;
  }
  auto start = Clock::now();

  // Ring buffer: the newest frame goes into the next slot (a copy, so callers reuse theirs).
  s.ring_head = (s.ring_head + 1) % static_cast<int>(s.ring.size());
  std::copy(depth.pixels.begin(), depth.pixels.end(),
            s.ring[static_cast<std::size_t>(s.ring_head)].pixels.begin());
  s.ring_count = std::min(s.ring_count + 1, static_cast<int>(s.ring.size()));

  s.mask_on = false;  // acquisition and calibration start from poses no mask was made for
  const bool searching = !s.have_pose || s.lost;
  s.box = searching ? Box{0, 0, s.width, s.height} : s.predicted_box(s.pose);
  const int valid = s.smooth(depth, s.box);
  s.smooth_spatially(s.box);
  report.times.smooth_ms = ms_since(start);
  if (valid < 50) {
    s.lost = s.have_pose;
    keep_last(searching ? TrackState::kBadInput : TrackState::kLost,
              searching ? "no valid depth in the frame" : "no valid depth where the face was");
    return;
  }

  State::IcpStats stats;
  bool recovered = false;
  if (searching) {
    start = Clock::now();
    const bool found = s.acquire(landmarks, stats);
    report.times.acquire_ms = ms_since(start);
    if (!found) {
      keep_last(s.have_pose ? TrackState::kLost : TrackState::kSearching, "no face found");
      if (s.have_pose) report.state = TrackState::kSearching;
      return;
    }
    recovered = s.have_pose;
    s.have_pose = true;
    s.lost = false;
    s.box = s.predicted_box(s.pose);
    s.smooth(depth, s.box);
    s.smooth_spatially(s.box);
  }

  start = Clock::now();
  s.mark_occluded(s.smoothed, s.box, s.pose, landmarks);
  stats = s.icp(s.smoothed, s.box, s.pose, s.options.icp_iterations, s.options.icp_first_gate_mm,
                s.options.icp_gate_mm);
  report.times.icp_ms = ms_since(start);
  report.samples_used = stats.used;
  report.inliers = stats.inliers;
  report.rms_mm = stats.rms;
  const bool face_seen = landmarks != nullptr && landmarks->points.size() >= 68;
  if (!s.acceptable(stats, false, face_seen)) {
    s.lost = true;
    s.pose = s.last_good_pose;
    keep_last(TrackState::kLost, stats.inliers < s.options.min_inliers ? "too few depth inliers"
                                 : stats.rms > s.max_rms_mm(face_seen) ? "residual too large"
                                                                       : "too few inliers");
    return;
  }

  start = Clock::now();
  // While calibrating the face is assumed neutral: expression weights would absorb the
  // identity difference the calibration is about to measure.
  // The mask of the ICP's start pose serves the weights too (ICP moves the face by a few mm,
  // far below the mask's margin).
  double refine_ms = 0.0;  // counted as ICP in the stage split, not as weights
  if (s.calibrated) {
    // ICP fitted the face with the last frame's weights. Where a shape moves little depth (a
    // brow against a pitch of the forehead), the pose takes part of this frame's expression
    // change and the weight solve the rest of the pose error; a few ICP iterations against the
    // face with this frame's first weights, then the remaining IRLS rounds, split them again.
    // The iterations are those of the weight solve split around them, so this costs only the
    // ICP iterations.
    const int iterations = s.options.weight_iterations;
    const bool refine = s.options.pose_refine_iterations > 0 && iterations > 1;
    s.solve_weights(s.smoothed, s.box, s.pose, refine ? 1 : iterations, !refine, landmarks,
                    report.landmarks_used);
    if (refine) {
      const auto refine_start = Clock::now();
      s.icp(s.smoothed, s.box, s.pose, s.options.pose_refine_iterations, s.options.icp_gate_mm,
            s.options.icp_gate_mm);
      refine_ms = ms_since(refine_start);
      s.solve_weights(s.smoothed, s.box, s.pose, iterations - 1, true, landmarks,
                      report.landmarks_used);
    }
  }
  s.mask_on = false;  // calibrate() below re-tracks stored frames: not this frame's mask
  report.times.icp_ms += refine_ms;
  report.times.weights_ms = ms_since(start) - refine_ms;
  s.previous_weights = s.weights;
  s.last_good_pose = s.pose;
  s.have_last_good = true;
  report.face_found = true;

  if (!s.calibrated) {
    const auto f = static_cast<std::size_t>(s.calib_count);
    std::copy(s.smoothed.pixels.begin(), s.smoothed.pixels.end(), s.calib_depth[f].pixels.begin());
    s.calib_box[f] = s.box;
    s.calib_pose[f] = s.pose;
    s.calib_weights[f] = s.weights;
    const bool have_landmarks = landmarks != nullptr && landmarks->points.size() >= 68;
    s.calib_landmark_scale[f] = have_landmarks ? s.landmark_scale(*landmarks) : 1.0f;
    for (std::size_t l = 0; l < 68; ++l) {
      const bool valid = have_landmarks && (landmarks->valid.empty() || landmarks->valid[l] != 0);
      s.calib_landmark_valid[f * 68 + l] = valid ? 1 : 0;
      if (valid) s.calib_landmarks[f * 68 + l] = landmarks->points[l];
    }
    ++s.calib_count;
    report.calibration_frames_left = s.options.calibration_frames - s.calib_count;
    if (s.calib_count >= s.options.calibration_frames) {
      start = Clock::now();
      const float fit_rms = s.calibrate();
      report.times.calibrate_ms = ms_since(start);
      s.filter.reset();
      // The fitted face must explain its own calibration frames as well as a re-acquisition
      // would have to (acquire_max_rms_mm); when it does not, the frames were not one neutral
      // face at a right pose (a lock on the wrong pose, the subject moving or talking), and the
      // tracker starts over rather than track with a wrong face.
      if (fit_rms > s.options.acquire_max_rms_mm) {
        reset();
        report.face_found = false;
        keep_last(TrackState::kSearching,
                  "calibration did not fit this face: face the camera with a neutral face and "
                  "hold still");
        return;
      }
    }
  }
  s.output(report, time_s);
  report.state = !s.calibrated ? TrackState::kCalibrating
                 : recovered   ? TrackState::kRecovered
                               : TrackState::kTracking;
}

}  // namespace fb
