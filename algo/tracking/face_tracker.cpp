#include "algo/tracking/face_tracker.hpp"

#include <algorithm>
#include <chrono>
#include <string>

#include "algo/core/clock.hpp"
#include "algo/tracking/acquisition.hpp"
#include "algo/tracking/calibrator.hpp"
#include "algo/tracking/depth_smoother.hpp"
#include "algo/tracking/occlusion_mask.hpp"
#include "algo/tracking/occlusion_report.hpp"
#include "algo/tracking/rigid_icp.hpp"
#include "algo/tracking/subject_rig.hpp"
#include "algo/tracking/tracker_geometry.hpp"
#include "algo/tracking/weight_solver.hpp"

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

namespace {

Result<void> check_inputs(const FaceModel& model, const PinholeIntrinsics& intrinsics,
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
  if (options.depth.temporal_frames < 1 || options.depth.temporal_frames > 16) {
    return fail("tracking: temporal_frames must be in [1, 16]");
  }
  if (options.calibration.calibration_frames < 1)
    return fail("tracking: calibration_frames must be >= 1");
  if (!(options.weights.landmark_noise_px > 0.0f))
    return fail("tracking: landmark_noise_px must be > 0");
  return success();
}

}  // namespace

// The rooms and the frame-to-frame state between them.
struct FaceTracker::State {
  const FaceModel* model = nullptr;  // non-owning; create() documents the lifetime
  TrackerOptions options;
  TrackerCamera camera;
  SubjectRig rig;
  DepthSmoother smoother;
  OcclusionMask mask;
  RigidIcp icp;
  WeightSolver solver;
  Calibrator calibrator;
  bool calibrated = false;

  RigidPoseF pose;  // raw ICP pose
  bool have_pose = false;
  RigidPoseF last_good_pose;
  bool have_last_good = false;
  bool lost = false;
  double last_time = 0.0;
  bool have_time = false;
  PoseFilter filter;
  RigidPose filtered;
  PixelRect box;             // the face box of this frame
  OcclusionState occlusion;  // what the report says (held while the face is searched for)

  PixelRect predicted_box(const RigidPoseF& p) const;
  IcpStats run_icp(const Image<float>& image, const PixelRect& b, RigidPoseF& p, int iterations,
                   float first_gate, float gate) const {
    return icp.run(rig, camera, mask, image, b, p, iterations, first_gate, gate);
  }
  void solve_weights(const Image<float>& image, const PixelRect& b, const RigidPoseF& p,
                     int iterations, bool final, const TrackLandmarks* landmarks,
                     int& landmarks_used) {
    solver.solve(rig, camera, mask, image, b, p, iterations, final, landmarks, landmarks_used);
  }
  // `face_seen`: landmarks say there is a face here (see max_fit_rms_mm()).
  bool acceptable(const IcpStats& s, bool acquiring, bool face_seen) const {
    return fit_acceptable(s, options.loss, acquiring,
                          max_fit_rms_mm(options.loss, calibrated, face_seen));
  }
  bool acquire(const TrackLandmarks* landmarks);
  // The frame's stages (track()); false: the report is final.
  bool search(const DepthImage& depth, const TrackLandmarks* landmarks, TrackReport& report);
  bool fit_pose(const TrackLandmarks* landmarks, TrackReport& report);
  void fit_weights(const TrackLandmarks* landmarks, TrackReport& report);
  bool collect_calibration_frame(FaceTracker& tracker, const TrackLandmarks* landmarks,
                                 TrackReport& report);
  void start_report(TrackReport& report) const;
  void keep_last(TrackReport& report, TrackState state, const char* reason) const;
  void output(TrackReport& report, double time_s);
};

PixelRect FaceTracker::State::predicted_box(const RigidPoseF& p) const {
  float u0 = 1e9f, v0 = 1e9f, u1 = -1e9f, v1 = -1e9f;
  for (int i = 0; i < rig.n; ++i) {
    const Eigen::Vector3f x = p.r * rig.sample(i) + p.t;
    if (x.z() <= 1.0f) continue;
    const Eigen::Vector2f px = camera.pixel_of(x);
    const float u = px.x(), v = px.y();
    u0 = std::min(u0, u), u1 = std::max(u1, u), v0 = std::min(v0, v), v1 = std::max(v1, v);
  }
  constexpr int kMargin = 16;  // px: a frame's motion plus the bilinear footprint
  PixelRect b;
  b.x0 = std::clamp(static_cast<int>(u0) - kMargin, 0, camera.width);
  b.y0 = std::clamp(static_cast<int>(v0) - kMargin, 0, camera.height);
  b.x1 = std::clamp(static_cast<int>(u1) + kMargin, 0, camera.width);
  b.y1 = std::clamp(static_cast<int>(v1) + kMargin, 0, camera.height);
  return b;
}

bool FaceTracker::State::acquire(const TrackLandmarks* landmarks) {
  const Image<float>& smoothed = smoother.smoothed();
  const PixelRect full = camera.full();
  const StartPoses candidates =
      start_poses(rig, camera, smoothed, landmarks, have_last_good ? &last_good_pose : nullptr,
                  options.depth.min_depth_mm, options.acquire);
  const bool from_landmarks = candidates.from_landmarks;
  // Acquisition accepts only a fit as good as tracking gives: most of the face's samples on the
  // surface (a face rotated far from the truth shows too few) with a residual near the sensor
  // noise (ICP can converge to a wrong rotation at the right place with a few mm RMS). Before
  // calibration the mean face fits a real one only to a few mm, so the RMS bound is then
  // acceptable()'s alone.
  const AcquireOptions& ao = options.acquire;
  auto good = [&](const IcpStats& s) {
    return acceptable(s, true, from_landmarks) &&
           static_cast<float>(s.inliers) >= ao.acquire_min_sample_fraction * rig.n &&
           (!calibrated || s.rms <= ao.acquire_max_rms_mm);
  };
  const RigidIcpOptions& io = options.icp;
  for (int c = 0; c < candidates.count; ++c) {
    RigidPoseF p = candidates.poses[static_cast<std::size_t>(c)];
    IcpStats s = run_icp(smoothed, full, p, ao.acquire_iterations, 40.0f, io.icp_gate_mm);
    if (!acceptable(s, true, from_landmarks)) continue;
    if (calibrated) {
      // The face may show any expression: fit the weights at this pose and refine it before
      // judging the residual (a neutral face on an open jaw leaves several mm).
      int unused = 0;
      solve_weights(smoothed, full, p, options.weights.weight_iterations, true, landmarks, unused);
      s = run_icp(smoothed, full, p, io.icp_iterations, io.icp_gate_mm, io.icp_gate_mm);
    }
    // With landmarks, a candidate must also put the model's landmarks on them.
    if (!good(s) || (from_landmarks &&
                     landmark_error_px(rig, camera, p, *landmarks) > ao.acquire_landmark_px)) {
      solver.weights = solver.previous_weights;
      rig.update_current(solver.weights);
      continue;
    }
    pose = p;
    return true;  // candidates are in order of evidence: the first good fit is the face
  }
  return false;
}

void FaceTracker::State::start_report(TrackReport& report) const {
  report.times = {};
  report.face_found = false;
  report.loss_reason = "";
  report.samples_used = report.inliers = report.landmarks_used = 0;
  report.rms_mm = 0.0f;
  report.calibration_frames_left = calibrated ? 0 : calibrator.frames_left();
  report.occluded_fraction = occlusion.fraction();  // held unless this frame measures
  report.occluded = occlusion.occluded();
}

void FaceTracker::State::keep_last(TrackReport& report, TrackState state,
                                   const char* reason) const {
  report.state = state;
  report.loss_reason = reason;
  report.camera_from_model = filtered;
  report.raw_camera_from_model = pose.to_rigid();
  report.shape_count = rig.k;
  for (int j = 0; j < rig.k; ++j)
    report.weights[static_cast<std::size_t>(j)] = solver.previous_weights[j];
}

bool FaceTracker::State::search(const DepthImage& depth, const TrackLandmarks* landmarks,
                                TrackReport& report) {
  const auto start = Clock::now();
  const bool found = acquire(landmarks);
  report.times.acquire_ms = ms_since(start);
  if (!found) {
    keep_last(report, have_pose ? TrackState::kLost : TrackState::kSearching, "no face found");
    if (have_pose) report.state = TrackState::kSearching;
    return false;
  }
  have_pose = true;
  lost = false;
  box = predicted_box(pose);
  smoother.smooth(depth, box);
  return true;
}

bool FaceTracker::State::fit_pose(const TrackLandmarks* landmarks, TrackReport& report) {
  const auto start = Clock::now();
  const Image<float>& smoothed = smoother.smoothed();
  mask.mark(options.occlusion, rig, camera, smoothed, box, pose, landmarks);
  const IcpStats stats = run_icp(smoothed, box, pose, options.icp.icp_iterations,
                                 options.icp.icp_first_gate_mm, options.icp.icp_gate_mm);
  report.times.icp_ms = ms_since(start);
  report.samples_used = stats.used;
  report.inliers = stats.inliers;
  report.rms_mm = stats.rms;
  // Measured before the loss test: a hand that covers enough of the face to lose it is
  // reported on that frame, and held while the face is searched for.
  occlusion.measure(mask.on ? hidden_fraction(stats.hidden, stats.facing) : 0.0f,
                    options.occlusion.occlusion_report_fraction);
  report.occluded_fraction = occlusion.fraction();
  report.occluded = occlusion.occluded();
  const bool face_seen = landmarks != nullptr && landmarks->points.size() >= 68;
  if (acceptable(stats, false, face_seen)) return true;
  lost = true;
  pose = last_good_pose;
  keep_last(report, TrackState::kLost,
            stats.inliers < options.loss.min_inliers ? "too few depth inliers"
            : stats.rms > max_fit_rms_mm(options.loss, calibrated, face_seen) ? "residual too large"
                                                                              : "too few inliers");
  return false;
}

void FaceTracker::State::fit_weights(const TrackLandmarks* landmarks, TrackReport& report) {
  const auto start = Clock::now();
  const Image<float>& smoothed = smoother.smoothed();
  // While calibrating the face is assumed neutral: expression weights would absorb the
  // identity difference the calibration is about to measure.
  // The mask of the ICP's start pose serves the weights too (ICP moves the face by a few mm,
  // far below the mask's margin).
  double refine_ms = 0.0;  // counted as ICP in the stage split, not as weights
  if (calibrated) {
    // ICP fitted the face with the last frame's weights. Where a shape moves little depth (a
    // brow against a pitch of the forehead), the pose takes part of this frame's expression
    // change and the weight solve the rest of the pose error; a few ICP iterations against the
    // face with this frame's first weights, then the remaining IRLS rounds, split them again.
    // The iterations are those of the weight solve split around them, so this costs only the
    // ICP iterations.
    const int iterations = options.weights.weight_iterations;
    const bool refine = options.weights.pose_refine_iterations > 0 && iterations > 1;
    solve_weights(smoothed, box, pose, refine ? 1 : iterations, !refine, landmarks,
                  report.landmarks_used);
    if (refine) {
      const auto refine_start = Clock::now();
      run_icp(smoothed, box, pose, options.weights.pose_refine_iterations, options.icp.icp_gate_mm,
              options.icp.icp_gate_mm);
      refine_ms = ms_since(refine_start);
      solve_weights(smoothed, box, pose, iterations - 1, true, landmarks, report.landmarks_used);
    }
  }
  mask.on = false;  // calibration re-tracks stored frames: not this frame's mask
  report.times.icp_ms += refine_ms;
  report.times.weights_ms = ms_since(start) - refine_ms;
}

bool FaceTracker::State::collect_calibration_frame(FaceTracker& tracker,
                                                   const TrackLandmarks* landmarks,
                                                   TrackReport& report) {
  calibrator.add_frame(smoother.smoothed(), box, pose, landmarks);
  report.calibration_frames_left = calibrator.frames_left();
  if (!calibrator.complete()) return true;
  const auto start = Clock::now();
  const float fit_rms = calibrator.calibrate(rig, icp, solver.weights);
  // Continue from the last calibration frame.
  pose = calibrator.last_pose();
  solver.previous_weights = solver.weights;
  calibrated = true;
  report.times.calibrate_ms = ms_since(start);
  filter.reset();
  // The fitted face must explain its own calibration frames as well as a re-acquisition
  // would have to (acquire_max_rms_mm); when it does not, the frames were not one neutral
  // face at a right pose (a lock on the wrong pose, the subject moving or talking), and the
  // tracker starts over rather than track with a wrong face.
  if (fit_rms <= options.acquire.acquire_max_rms_mm) return true;
  tracker.reset();
  report.face_found = false;
  keep_last(report, TrackState::kSearching,
            "calibration did not fit this face: face the camera with a neutral face and "
            "hold still");
  return false;
}

void FaceTracker::State::output(TrackReport& report, double time_s) {
  const double dt = have_time ? time_s - last_time : 0.0;
  filtered = filter.update(pose.to_rigid(), dt);
  last_time = time_s;
  have_time = true;
  report.camera_from_model = filtered;
  report.raw_camera_from_model = pose.to_rigid();
  report.shape_count = rig.k;
  std::fill(report.weights.begin(), report.weights.end(), 0.0f);
  for (int j = 0; j < rig.k; ++j) report.weights[static_cast<std::size_t>(j)] = solver.weights[j];
  std::fill(report.weight_sigma.begin(), report.weight_sigma.end(), 0.0f);
  if (options.weights.report_weight_sigma)
    for (int j = 0; j < rig.k; ++j)
      report.weight_sigma[static_cast<std::size_t>(j)] = solver.weight_sigma[j];
}

FaceTracker::FaceTracker(std::unique_ptr<State> state) : state_(std::move(state)) {}
FaceTracker::~FaceTracker() = default;

Result<std::unique_ptr<FaceTracker>> FaceTracker::create(const FaceModel& model,
                                                         const PinholeIntrinsics& intrinsics,
                                                         const TrackerOptions& options) {
  if (auto ok = check_inputs(model, intrinsics, options); !ok) return ok.failure();
  auto rig = SubjectRig::create(model, options.samples, options.weights,
                                options.calibration.identity_modes);
  if (!rig) return rig.failure();
  auto s = std::make_unique<State>();
  s->model = &model;
  s->options = options;
  s->camera = TrackerCamera::from(intrinsics);
  s->rig = std::move(*rig);
  const int n = s->rig.n, k = s->rig.k;
  s->smoother.allocate(options.depth, s->camera.width, s->camera.height);
  s->mask.allocate(n);
  s->icp = RigidIcp(options.icp);
  s->solver.allocate(options.weights, options.icp.icp_gate_mm, n, k);
  s->calibrator.allocate(options.calibration, s->camera, options.weights.landmark_huber_px,
                         options.weights.landmark_noise_px, n);
  s->filter = PoseFilter(options.pose_filter);
  s->rig.build({}, s->solver.weights);
  return std::unique_ptr<FaceTracker>(new FaceTracker(std::move(s)));
}

Result<void> FaceTracker::set_identity(std::span<const float> coefficients) {
  State& s = *state_;
  if (coefficients.size() > static_cast<std::size_t>(s.model->identity_count)) {
    return fail("tracking: " + std::to_string(coefficients.size()) +
                " identity coefficients given, the model has " +
                std::to_string(s.model->identity_count));
  }
  s.rig.use_model_expressions();
  s.rig.landmark_offset.setZero();  // measured by calibration only
  s.rig.build(coefficients, s.solver.weights);
  s.rig.build_subject_blendshapes(s.solver.weights);
  s.calibrated = true;
  s.calibrator.clear();
  return success();
}

Result<void> FaceTracker::set_rig(const TrackerRig& rig) {
  State& s = *state_;
  if (auto loaded = s.rig.load(rig, s.solver.weights); !loaded) return loaded;
  s.calibrated = true;
  s.calibrator.clear();
  return success();
}

void FaceTracker::set_subject_blendshapes(const SubjectBlendshapes* source) {
  state_->rig.subject_blendshapes = source;
}

void FaceTracker::reset() {
  State& s = *state_;
  s.calibrated = false;
  s.calibrator.clear();
  s.have_pose = s.have_last_good = s.lost = s.have_time = false;
  s.smoother.clear();
  s.solver.weights.setZero();
  s.solver.previous_weights.setZero();
  s.filter.reset();
  s.occlusion.reset();
  s.rig.landmark_offset.setZero();
  s.rig.use_model_expressions();
  s.rig.build({}, s.solver.weights);
}

bool FaceTracker::calibrated() const {
  return state_->calibrated;
}
std::span<const float> FaceTracker::identity() const {
  return state_->rig.identity;
}
int FaceTracker::sample_count() const {
  return state_->rig.n;
}
int FaceTracker::shape_count() const {
  return state_->rig.k;
}
std::span<const int> FaceTracker::weak_shapes() const {
  return state_->rig.weak_shapes;
}
std::span<const std::string> FaceTracker::shape_names() const {
  return std::span<const std::string>(state_->model->expression_names)
      .first(static_cast<std::size_t>(state_->rig.k));
}

void FaceTracker::track(const DepthImage& depth, double time_s, const TrackLandmarks* landmarks,
                        TrackReport& report) {
  State& s = *state_;
  s.start_report(report);
  if (depth.width != s.camera.width || depth.height != s.camera.height ||
      depth.pixels.size() != static_cast<std::size_t>(s.camera.width) * s.camera.height) {
    s.keep_last(report, TrackState::kBadInput,
                "depth frame size does not match the camera intrinsics");
    return;
  }
  const auto start = Clock::now();
  s.smoother.push(depth);
  s.mask.on = false;  // acquisition and calibration start from poses no mask was made for
  const bool searching = !s.have_pose || s.lost;
  s.box = searching ? s.camera.full() : s.predicted_box(s.pose);
  const int valid = s.smoother.smooth(depth, s.box);
  report.times.smooth_ms = ms_since(start);
  if (valid < 50) {
    s.lost = s.have_pose;
    s.keep_last(report, searching ? TrackState::kBadInput : TrackState::kLost,
                searching ? "no valid depth in the frame" : "no valid depth where the face was");
    return;
  }
  const bool recovered = searching && s.have_pose;
  if (searching && !s.search(depth, landmarks, report)) return;
  if (!s.fit_pose(landmarks, report)) return;
  s.fit_weights(landmarks, report);
  s.solver.previous_weights = s.solver.weights;
  s.last_good_pose = s.pose;
  s.have_last_good = true;
  report.face_found = true;
  // A frame with the face occluded is no calibration frame: the identity would be fitted to
  // the face with a hand in front of it (its samples are masked, but so much of the face is
  // missing that hair and noise pull the fit).
  if (!s.calibrated && !report.occluded && !s.collect_calibration_frame(*this, landmarks, report))
    return;
  s.output(report, time_s);
  report.state = !s.calibrated ? TrackState::kCalibrating
                 : recovered   ? TrackState::kRecovered
                               : TrackState::kTracking;
}

}  // namespace fb
