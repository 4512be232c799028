#include "sim/scoring/take_runner.hpp"
#include "algo/core/clock.hpp"

#include <time.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <numeric>
#include <span>
#include <string_view>
#include <type_traits>
#include <utility>

#include "storage/durable_file.hpp"

namespace fb::cli {

double thread_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

namespace {

// Sets one tracker option, (options.*Group).*Member = value: ints truncated, booleans 0 / 1.
template <auto Group, auto Member>
void set_option(TrackerOptions& options, double value) {
  auto& field = (options.*Group).*Member;
  using T = std::remove_reference_t<decltype(field)>;
  if constexpr (std::is_same_v<T, bool>) {
    field = value != 0.0;
  } else {
    field = static_cast<T>(value);
  }
}

// Each key is the option's own name (its field in its room's group, tracker_options.hpp).
const std::pair<std::string_view, void (*)(TrackerOptions&, double)> kFields[] = {
    {"temporal_frames",
     &set_option<&TrackerOptions::depth, &DepthSmootherOptions::temporal_frames>},
    {"temporal_range_mm",
     &set_option<&TrackerOptions::depth, &DepthSmootherOptions::temporal_range_mm>},
    {"spatial_radius_px",
     &set_option<&TrackerOptions::depth, &DepthSmootherOptions::spatial_radius_px>},
    {"spatial_range_mm",
     &set_option<&TrackerOptions::depth, &DepthSmootherOptions::spatial_range_mm>},
    {"temporal_decay", &set_option<&TrackerOptions::depth, &DepthSmootherOptions::temporal_decay>},
    {"temporal_weight",
     &set_option<&TrackerOptions::weights, &WeightSolverOptions::temporal_weight>},
    {"sparsity", &set_option<&TrackerOptions::weights, &WeightSolverOptions::sparsity>},
    {"sparsity_signal_power",
     &set_option<&TrackerOptions::weights, &WeightSolverOptions::sparsity_signal_power>},
    {"support_sparsity",
     &set_option<&TrackerOptions::weights, &WeightSolverOptions::support_sparsity>},
    {"stale_temporal_floor",
     &set_option<&TrackerOptions::weights, &WeightSolverOptions::stale_temporal_floor>},
    {"ridge", &set_option<&TrackerOptions::weights, &WeightSolverOptions::ridge>},
    {"landmark_weight",
     &set_option<&TrackerOptions::weights, &WeightSolverOptions::landmark_weight>},
    {"weight_iterations",
     &set_option<&TrackerOptions::weights, &WeightSolverOptions::weight_iterations>},
    {"icp_gate_mm", &set_option<&TrackerOptions::icp, &RigidIcpOptions::icp_gate_mm>},
    {"identity_prior",
     &set_option<&TrackerOptions::calibration, &CalibratorOptions::identity_prior>},
    {"calibrate_depth_offsets",
     &set_option<&TrackerOptions::calibration, &CalibratorOptions::calibrate_depth_offsets>},
    {"max_depth_offset_mm",
     &set_option<&TrackerOptions::calibration, &CalibratorOptions::max_depth_offset_mm>},
    {"antagonist_weight",
     &set_option<&TrackerOptions::weights, &WeightSolverOptions::antagonist_weight>},
    {"calibration_frames",
     &set_option<&TrackerOptions::calibration, &CalibratorOptions::calibration_frames>},
    {"calibration_rounds",
     &set_option<&TrackerOptions::calibration, &CalibratorOptions::calibration_rounds>},
    {"level_gain", &set_option<&TrackerOptions::pose_filter, &PoseFilterOptions::level_gain>},
    {"trend_gain", &set_option<&TrackerOptions::pose_filter, &PoseFilterOptions::trend_gain>},
    {"rest_level_gain",
     &set_option<&TrackerOptions::pose_filter, &PoseFilterOptions::rest_level_gain>},
    {"sample_spacing_mm",
     &set_option<&TrackerOptions::samples, &RigSampleOptions::sample_spacing_mm>},
    {"extra_samples_per_shape",
     &set_option<&TrackerOptions::samples, &RigSampleOptions::extra_samples_per_shape>},
    {"hole_margin_mm", &set_option<&TrackerOptions::samples, &RigSampleOptions::hole_margin_mm>},
    {"hold_gaze_shapes",
     &set_option<&TrackerOptions::weights, &WeightSolverOptions::hold_gaze_shapes>},
    {"on_shape_sparsity",
     &set_option<&TrackerOptions::weights, &WeightSolverOptions::on_shape_sparsity>},
    {"on_shape_min_weight",
     &set_option<&TrackerOptions::weights, &WeightSolverOptions::on_shape_min_weight>},
    {"on_shape_max_signal",
     &set_option<&TrackerOptions::weights, &WeightSolverOptions::on_shape_max_signal>},
    {"weak_shape_fraction",
     &set_option<&TrackerOptions::weights, &WeightSolverOptions::weak_shape_fraction>},
    {"weak_shape_ridge",
     &set_option<&TrackerOptions::weights, &WeightSolverOptions::weak_shape_ridge>},
    {"keep_identity_rigid",
     &set_option<&TrackerOptions::calibration, &CalibratorOptions::keep_identity_rigid>},
    {"weight_tukey_k", &set_option<&TrackerOptions::weights, &WeightSolverOptions::weight_tukey_k>},
    {"weight_min_gate_mm",
     &set_option<&TrackerOptions::weights, &WeightSolverOptions::weight_min_gate_mm>},
    {"calibrate_landmark_offsets",
     &set_option<&TrackerOptions::calibration, &CalibratorOptions::calibrate_landmark_offsets>},
    {"max_landmark_offset_mm",
     &set_option<&TrackerOptions::calibration, &CalibratorOptions::max_landmark_offset_mm>},
    {"landmark_offset_depth_gate_mm",
     &set_option<&TrackerOptions::calibration, &CalibratorOptions::landmark_offset_depth_gate_mm>},
    {"prior_noise_reference_mm",
     &set_option<&TrackerOptions::weights, &WeightSolverOptions::prior_noise_reference_mm>},
    {"max_prior_noise_scale",
     &set_option<&TrackerOptions::weights, &WeightSolverOptions::max_prior_noise_scale>},
    {"max_hidden_landmark_fraction",
     &set_option<&TrackerOptions::occlusion, &OcclusionMaskOptions::max_hidden_landmark_fraction>},
    {"landmark_huber_px",
     &set_option<&TrackerOptions::weights, &WeightSolverOptions::landmark_huber_px>},
    {"calibration_landmark_weight",
     &set_option<&TrackerOptions::calibration, &CalibratorOptions::calibration_landmark_weight>},
    {"uncalibrated_max_rms_mm",
     &set_option<&TrackerOptions::loss, &LossOptions::uncalibrated_max_rms_mm>},
    {"icp_iterations", &set_option<&TrackerOptions::icp, &RigidIcpOptions::icp_iterations>},
    {"pose_refine_iterations",
     &set_option<&TrackerOptions::weights, &WeightSolverOptions::pose_refine_iterations>},
    {"icp_converged_rad", &set_option<&TrackerOptions::icp, &RigidIcpOptions::icp_converged_rad>},
    {"icp_converged_mm", &set_option<&TrackerOptions::icp, &RigidIcpOptions::icp_converged_mm>},
    {"hidden_hold", &set_option<&TrackerOptions::weights, &WeightSolverOptions::hidden_hold>},
    {"occluder_margin_mm",
     &set_option<&TrackerOptions::occlusion, &OcclusionMaskOptions::occluder_margin_mm>},
    {"occluder_radius_px",
     &set_option<&TrackerOptions::occlusion, &OcclusionMaskOptions::occluder_radius_px>},
    {"occlusion_report_fraction",
     &set_option<&TrackerOptions::occlusion, &OcclusionMaskOptions::occlusion_report_fraction>},
    {"report_weight_sigma",
     &set_option<&TrackerOptions::weights, &WeightSolverOptions::report_weight_sigma>},
};

}  // namespace

Result<TrackerOptions> tracker_overrides(const std::string& text) {
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
    const auto* field = std::find_if(std::begin(kFields), std::end(kFields),
                                     [&](const auto& f) { return f.first == key; });
    if (field == std::end(kFields)) {
      std::string known;
      for (const auto& f : kFields) known += (known.empty() ? "" : ", ") + std::string(f.first);
      return fail("--set: unknown key '" + std::string(key) + "' (known: " + known + ")");
    }
    field->second(o, v);
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
  if (run.bilinear != nullptr && run.known_identity)
    return fail("a known identity is in the face model's modes, not a bilinear model's");
  const FaceModel& tracker_model = run.bilinear ? run.bilinear->tracking.face : model;
  auto tracker = FaceTracker::create(tracker_model, take.intrinsics, run.tracker);
  if (!tracker) return tracker.failure();
  if (run.bilinear != nullptr) (*tracker)->set_subject_blendshapes(&*run.bilinear->blendshapes);
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
  if (run.reacquire != nullptr) run.reacquire->reset();
  bool face_before = false;
  for (std::size_t f = 0; f < take.frames.size(); ++f) {
    const TakeFrame& tf = take.frames[f];
    TrackLandmarks landmarks{tf.landmarks, {}};
    const auto arrival = Clock::now();
    const double cpu0 = thread_cpu_ms();
    const TrackLandmarks* used = run.landmarks ? &landmarks : nullptr;
    FrameResult r;
    TrackLandmarkSource* source = run.dlib;
    if (source == nullptr && used == nullptr && run.reacquire != nullptr &&
        (!face_before || !(*tracker)->calibrated()))
      source = run.reacquire;
    if (source != nullptr) {
      const LandmarkFrameResult found = source->detect(tf.color, tf.depth);
      used = source->landmarks();
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
    // Lost: the next detection searches the whole image, not around the last face.
    if (face_before && !report.face_found && run.reacquire != nullptr) run.reacquire->reset();
    face_before = report.face_found;
    if (run.sender) {
      out.index = f;
      out.time_s = static_cast<double>(f) / 30.0;
      out.face_found = report.face_found;
      out.occluded = report.occluded;
      out.occluded_fraction = report.occluded_fraction;
      out.camera_from_model = report.camera_from_model;
      mapping.to_arkit(std::span<const float>(report.weights.data(), static_cast<std::size_t>(k)),
                       out.weights);
      if (auto sent = run.sender->send(out); !sent) return sent.failure();
      r.latency_ms = ms_since(arrival);
    }
    r.state = report.state;
    r.calibrated = (*tracker)->calibrated();
    r.times = report.times;
    r.cpu_ms = cpu1 - cpu0;
    r.landmarks_used = report.landmarks_used;
    r.occluded = report.occluded;
    r.occluded_fraction = report.occluded_fraction;
    r.abs_error.resize(static_cast<std::size_t>(k));
    for (int j = 0; j < k; ++j) {
      const float truth = static_cast<std::size_t>(j) < tf.truth.expression_weights.size()
                              ? tf.truth.expression_weights[static_cast<std::size_t>(j)]
                              : 0.0f;
      r.abs_error[static_cast<std::size_t>(j)] =
          std::abs(report.weights[static_cast<std::size_t>(j)] - truth);
    }
    if (run.tracker.weights.report_weight_sigma)
      r.weight_sigma.assign(report.weight_sigma.begin(), report.weight_sigma.begin() + k);
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
