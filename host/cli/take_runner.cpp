#include "host/cli/take_runner.hpp"

#include <time.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <span>
#include <string_view>
#include <utility>

namespace fb::cli {

double ms_between(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

double thread_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

Result<LandmarkDetector> load_landmark_detector(const std::string& option) {
  const std::filesystem::path path = option.empty() ? kShapePredictor : option;
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    return fail("cannot read the landmark model " + path.string() +
                " (install Debian's libdlib-data or pass --shape-predictor PATH)");
  }
  return LandmarkDetector::create(in);
}

Result<TrackerOptions> tracker_overrides(const std::string& text) {
  using Setter = void (*)(TrackerOptions&, double);
  static constexpr std::pair<std::string_view, Setter> kSetters[] = {
      {"temporal_frames",
       [](TrackerOptions& o, double v) { o.temporal_frames = static_cast<int>(v); }},
      {"temporal_range_mm",
       [](TrackerOptions& o, double v) { o.temporal_range_mm = static_cast<float>(v); }},
      {"spatial_radius_px",
       [](TrackerOptions& o, double v) { o.spatial_radius_px = static_cast<int>(v); }},
      {"spatial_range_mm",
       [](TrackerOptions& o, double v) { o.spatial_range_mm = static_cast<float>(v); }},
      {"temporal_decay",
       [](TrackerOptions& o, double v) { o.temporal_decay = static_cast<float>(v); }},
      {"temporal_weight",
       [](TrackerOptions& o, double v) { o.temporal_weight = static_cast<float>(v); }},
      {"sparsity", [](TrackerOptions& o, double v) { o.sparsity = static_cast<float>(v); }},
      {"sparsity_signal_power",
       [](TrackerOptions& o, double v) { o.sparsity_signal_power = static_cast<float>(v); }},
      {"support_sparsity",
       [](TrackerOptions& o, double v) { o.support_sparsity = static_cast<float>(v); }},
      {"stale_temporal_floor",
       [](TrackerOptions& o, double v) { o.stale_temporal_floor = static_cast<float>(v); }},
      {"ridge", [](TrackerOptions& o, double v) { o.ridge = static_cast<float>(v); }},
      {"landmark_weight",
       [](TrackerOptions& o, double v) { o.landmark_weight = static_cast<float>(v); }},
      {"weight_iterations",
       [](TrackerOptions& o, double v) { o.weight_iterations = static_cast<int>(v); }},
      {"icp_gate_mm", [](TrackerOptions& o, double v) { o.icp_gate_mm = static_cast<float>(v); }},
      {"identity_prior",
       [](TrackerOptions& o, double v) { o.identity_prior = static_cast<float>(v); }},
      {"calibrate_depth_offsets",
       [](TrackerOptions& o, double v) { o.calibrate_depth_offsets = v != 0.0; }},
      {"max_depth_offset_mm",
       [](TrackerOptions& o, double v) { o.max_depth_offset_mm = static_cast<float>(v); }},
      {"antagonist_weight",
       [](TrackerOptions& o, double v) { o.antagonist_weight = static_cast<float>(v); }},
      {"calibration_frames",
       [](TrackerOptions& o, double v) { o.calibration_frames = static_cast<int>(v); }},
      {"calibration_rounds",
       [](TrackerOptions& o, double v) { o.calibration_rounds = static_cast<int>(v); }},
      {"level_gain", [](TrackerOptions& o, double v) { o.pose_filter.level_gain = v; }},
      {"trend_gain", [](TrackerOptions& o, double v) { o.pose_filter.trend_gain = v; }},
      {"rest_level_gain", [](TrackerOptions& o, double v) { o.pose_filter.rest_level_gain = v; }},
      {"sample_spacing_mm",
       [](TrackerOptions& o, double v) { o.sample_spacing_mm = static_cast<float>(v); }},
      {"extra_samples_per_shape",
       [](TrackerOptions& o, double v) { o.extra_samples_per_shape = static_cast<int>(v); }},
      {"hole_margin_mm",
       [](TrackerOptions& o, double v) { o.hole_margin_mm = static_cast<float>(v); }},
      {"hold_gaze_shapes", [](TrackerOptions& o, double v) { o.hold_gaze_shapes = v != 0; }},
      {"on_shape_sparsity",
       [](TrackerOptions& o, double v) { o.on_shape_sparsity = static_cast<float>(v); }},
      {"on_shape_min_weight",
       [](TrackerOptions& o, double v) { o.on_shape_min_weight = static_cast<float>(v); }},
      {"on_shape_max_signal",
       [](TrackerOptions& o, double v) { o.on_shape_max_signal = static_cast<float>(v); }},
      {"weak_shape_fraction",
       [](TrackerOptions& o, double v) { o.weak_shape_fraction = static_cast<float>(v); }},
      {"weak_shape_ridge",
       [](TrackerOptions& o, double v) { o.weak_shape_ridge = static_cast<float>(v); }},
      {"keep_identity_rigid",
       [](TrackerOptions& o, double v) { o.keep_identity_rigid = v != 0.0; }},
      {"weight_tukey_k",
       [](TrackerOptions& o, double v) { o.weight_tukey_k = static_cast<float>(v); }},
      {"weight_min_gate_mm",
       [](TrackerOptions& o, double v) { o.weight_min_gate_mm = static_cast<float>(v); }},
      {"calibrate_landmark_offsets",
       [](TrackerOptions& o, double v) { o.calibrate_landmark_offsets = v != 0.0; }},
      {"max_landmark_offset_mm",
       [](TrackerOptions& o, double v) { o.max_landmark_offset_mm = static_cast<float>(v); }},
      {"max_hidden_landmark_fraction",
       [](TrackerOptions& o, double v) { o.max_hidden_landmark_fraction = static_cast<float>(v); }},
      {"landmark_huber_px",
       [](TrackerOptions& o, double v) { o.landmark_huber_px = static_cast<float>(v); }},
      {"calibration_landmark_weight",
       [](TrackerOptions& o, double v) { o.calibration_landmark_weight = static_cast<float>(v); }},
      {"uncalibrated_max_rms_mm",
       [](TrackerOptions& o, double v) { o.uncalibrated_max_rms_mm = static_cast<float>(v); }},
      {"icp_iterations",
       [](TrackerOptions& o, double v) { o.icp_iterations = static_cast<int>(v); }},
      {"pose_refine_iterations",
       [](TrackerOptions& o, double v) { o.pose_refine_iterations = static_cast<int>(v); }},
      {"icp_converged_rad",
       [](TrackerOptions& o, double v) { o.icp_converged_rad = static_cast<float>(v); }},
      {"icp_converged_mm",
       [](TrackerOptions& o, double v) { o.icp_converged_mm = static_cast<float>(v); }},
      {"hidden_hold", [](TrackerOptions& o, double v) { o.hidden_hold = static_cast<float>(v); }},
      {"occluder_margin_mm",
       [](TrackerOptions& o, double v) { o.occluder_margin_mm = static_cast<float>(v); }},
      {"occluder_radius_px",
       [](TrackerOptions& o, double v) { o.occluder_radius_px = static_cast<int>(v); }},
  };
  TrackerOptions o;
  std::size_t start = 0;
  while (start < text.size()) {
    const auto comma = text.find(',', start);
    const std::string item =
        text.substr(start, comma == std::string::npos ? text.npos : comma - start);
    start = comma == std::string::npos ? text.size() : comma + 1;
    const auto eq = item.find('=');
    if (eq == std::string::npos) return fail("--set: expected key=value, got '" + item + "'");
    const std::string_view key = std::string_view(item).substr(0, eq);
    char* parsed_end = nullptr;
    const double v = std::strtod(item.c_str() + eq + 1, &parsed_end);
    if (parsed_end == item.c_str() + eq + 1 || *parsed_end != '\0')
      return fail("--set: '" + item + "' needs a number after '='");
    const auto* setter = std::find_if(std::begin(kSetters), std::end(kSetters),
                                      [&](const auto& s) { return s.first == key; });
    if (setter == std::end(kSetters)) {
      std::string known;
      for (const auto& s : kSetters) known += (known.empty() ? "" : ", ") + std::string(s.first);
      return fail("--set: unknown key '" + std::string(key) + "' (known: " + known + ")");
    }
    setter->second(o, v);
  }
  return o;
}

RigidPose compose(const RigidPose& a, const RigidPose& b) {
  RigidPose p;
  p.rotation = (a.rotation * b.rotation).normalized();
  p.translation = a.rotation * b.translation + a.translation;
  return p;
}

double rotation_error_deg(const RigidPose& a, const RigidPose& b) {
  return Eigen::AngleAxisd(a.rotation.conjugate() * b.rotation).angle() * kDeg;
}

Result<std::vector<FrameResult>> run_take(const FaceModel& model, const ArkitMapping& mapping,
                                          const RenderedTake& take, const RunOptions& run) {
  auto tracker = FaceTracker::create(model, take.intrinsics, run.tracker);
  if (!tracker) return tracker.failure();
  if (run.known_identity && !take.frames.empty()) {
    if (auto r = (*tracker)->set_identity(take.frames[0].truth.identity_coeffs); !r) {
      return r.failure();
    }
  }
  const int k = model.fitting_expression_count;
  std::vector<FrameResult> results;
  results.reserve(take.frames.size());
  TrackReport report;
  ArkitFrame out;
  for (std::size_t f = 0; f < take.frames.size(); ++f) {
    const TakeFrame& tf = take.frames[f];
    TrackLandmarks landmarks{tf.landmarks, {}};
    const auto arrival = Clock::now();
    const double cpu0 = thread_cpu_ms();
    const TrackLandmarks* used = run.landmarks ? &landmarks : nullptr;
    FrameResult r;
    if (run.dlib != nullptr) {
      const LandmarkFrameResult found = run.dlib->detect(tf.color, tf.depth);
      used = run.dlib->landmarks();
      r.landmark_ms = found.ms;
      r.detected = found.found;
      if (used != nullptr) {
        for (std::size_t l = 17; l < 68; ++l) {
          if (!used->valid.empty() && !used->valid[l]) continue;
          const Eigen::Vector2f e = used->points[l] - tf.truth.landmarks_depth_px[l].cast<float>();
          r.landmark_sq_error_px2 += e.squaredNorm();
          r.landmark_axes += 2;
        }
      }
    }
    (*tracker)->track(tf.depth, static_cast<double>(f) / 30.0, used, report);
    const double cpu1 = thread_cpu_ms();
    if (run.sender) {
      out.index = f;
      out.time_s = static_cast<double>(f) / 30.0;
      out.face_found = report.face_found;
      out.camera_from_model = report.camera_from_model;
      mapping.to_arkit(std::span<const float>(report.weights.data(), static_cast<std::size_t>(k)),
                       out.weights);
      if (auto sent = run.sender->send(out); !sent) return sent.failure();
      r.latency_ms = ms_between(arrival, Clock::now());
    }
    r.state = report.state;
    r.calibrated = (*tracker)->calibrated();
    r.times = report.times;
    r.cpu_ms = cpu1 - cpu0;
    r.landmarks_used = report.landmarks_used;
    r.abs_error.resize(static_cast<std::size_t>(k));
    for (int j = 0; j < k; ++j) {
      const float truth = static_cast<std::size_t>(j) < tf.truth.expression_weights.size()
                              ? tf.truth.expression_weights[static_cast<std::size_t>(j)]
                              : 0.0f;
      r.abs_error[static_cast<std::size_t>(j)] =
          std::abs(report.weights[static_cast<std::size_t>(j)] - truth);
    }
    const RigidPose& truth_pose = tf.truth.camera_from_model;
    const Eigen::Vector3d c = take.take.face_centre_model;
    r.rotation_error_deg = rotation_error_deg(report.camera_from_model, truth_pose);
    r.centre_error_mm = (report.camera_from_model.apply(c) - truth_pose.apply(c)).norm();
    r.origin_error_mm = (report.camera_from_model.translation - truth_pose.translation).norm();
    r.raw_rotation_error_deg = rotation_error_deg(report.raw_camera_from_model, truth_pose);
    r.raw_centre_error_mm = (report.raw_camera_from_model.apply(c) - truth_pose.apply(c)).norm();
    r.estimate = report.camera_from_model;
    r.truth = truth_pose;
    results.push_back(std::move(r));
  }
  if (run.identity_out != nullptr) {
    const auto id = (*tracker)->identity();
    run.identity_out->assign(id.begin(), id.end());
  }
  return results;
}
bool tracked(TrackState s) {
  return s == TrackState::kTracking || s == TrackState::kRecovered;
}

}  // namespace fb::cli
