#include "host/cli/take_runner.hpp"
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
#include <variant>

#include "storage/durable_file.hpp"

namespace fb::cli {

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
  // Each key is the option's own name; ints take the value truncated, booleans 0 / 1.
  using Field = std::variant<float TrackerOptions::*, int TrackerOptions::*, bool TrackerOptions::*,
                             double PoseFilterOptions::*>;
  static const std::pair<std::string_view, Field> kFields[] = {
      {"temporal_frames", &TrackerOptions::temporal_frames},
      {"temporal_range_mm", &TrackerOptions::temporal_range_mm},
      {"spatial_radius_px", &TrackerOptions::spatial_radius_px},
      {"spatial_range_mm", &TrackerOptions::spatial_range_mm},
      {"temporal_decay", &TrackerOptions::temporal_decay},
      {"temporal_weight", &TrackerOptions::temporal_weight},
      {"sparsity", &TrackerOptions::sparsity},
      {"sparsity_signal_power", &TrackerOptions::sparsity_signal_power},
      {"support_sparsity", &TrackerOptions::support_sparsity},
      {"stale_temporal_floor", &TrackerOptions::stale_temporal_floor},
      {"ridge", &TrackerOptions::ridge},
      {"landmark_weight", &TrackerOptions::landmark_weight},
      {"weight_iterations", &TrackerOptions::weight_iterations},
      {"icp_gate_mm", &TrackerOptions::icp_gate_mm},
      {"identity_prior", &TrackerOptions::identity_prior},
      {"calibrate_depth_offsets", &TrackerOptions::calibrate_depth_offsets},
      {"max_depth_offset_mm", &TrackerOptions::max_depth_offset_mm},
      {"antagonist_weight", &TrackerOptions::antagonist_weight},
      {"calibration_frames", &TrackerOptions::calibration_frames},
      {"calibration_rounds", &TrackerOptions::calibration_rounds},
      {"level_gain", &PoseFilterOptions::level_gain},
      {"trend_gain", &PoseFilterOptions::trend_gain},
      {"rest_level_gain", &PoseFilterOptions::rest_level_gain},
      {"sample_spacing_mm", &TrackerOptions::sample_spacing_mm},
      {"extra_samples_per_shape", &TrackerOptions::extra_samples_per_shape},
      {"hole_margin_mm", &TrackerOptions::hole_margin_mm},
      {"hold_gaze_shapes", &TrackerOptions::hold_gaze_shapes},
      {"on_shape_sparsity", &TrackerOptions::on_shape_sparsity},
      {"on_shape_min_weight", &TrackerOptions::on_shape_min_weight},
      {"on_shape_max_signal", &TrackerOptions::on_shape_max_signal},
      {"weak_shape_fraction", &TrackerOptions::weak_shape_fraction},
      {"weak_shape_ridge", &TrackerOptions::weak_shape_ridge},
      {"keep_identity_rigid", &TrackerOptions::keep_identity_rigid},
      {"weight_tukey_k", &TrackerOptions::weight_tukey_k},
      {"weight_min_gate_mm", &TrackerOptions::weight_min_gate_mm},
      {"calibrate_landmark_offsets", &TrackerOptions::calibrate_landmark_offsets},
      {"max_landmark_offset_mm", &TrackerOptions::max_landmark_offset_mm},
      {"landmark_offset_depth_gate_mm", &TrackerOptions::landmark_offset_depth_gate_mm},
      {"prior_noise_reference_mm", &TrackerOptions::prior_noise_reference_mm},
      {"max_prior_noise_scale", &TrackerOptions::max_prior_noise_scale},
      {"max_hidden_landmark_fraction", &TrackerOptions::max_hidden_landmark_fraction},
      {"landmark_huber_px", &TrackerOptions::landmark_huber_px},
      {"calibration_landmark_weight", &TrackerOptions::calibration_landmark_weight},
      {"uncalibrated_max_rms_mm", &TrackerOptions::uncalibrated_max_rms_mm},
      {"icp_iterations", &TrackerOptions::icp_iterations},
      {"pose_refine_iterations", &TrackerOptions::pose_refine_iterations},
      {"icp_converged_rad", &TrackerOptions::icp_converged_rad},
      {"icp_converged_mm", &TrackerOptions::icp_converged_mm},
      {"hidden_hold", &TrackerOptions::hidden_hold},
      {"occluder_margin_mm", &TrackerOptions::occluder_margin_mm},
      {"occluder_radius_px", &TrackerOptions::occluder_radius_px},
      {"occlusion_report_fraction", &TrackerOptions::occlusion_report_fraction},
      {"report_weight_sigma", &TrackerOptions::report_weight_sigma},
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
    const auto* field = std::find_if(std::begin(kFields), std::end(kFields),
                                     [&](const auto& f) { return f.first == key; });
    if (field == std::end(kFields)) {
      std::string known;
      for (const auto& f : kFields) known += (known.empty() ? "" : ", ") + std::string(f.first);
      return fail("--set: unknown key '" + std::string(key) + "' (known: " + known + ")");
    }
    std::visit(
        [&](auto member) {
          if constexpr (std::is_same_v<decltype(member), double PoseFilterOptions::*>) {
            o.pose_filter.*member = v;
          } else if constexpr (std::is_same_v<decltype(member), bool TrackerOptions::*>) {
            o.*member = v != 0.0;
          } else {
            using T = std::remove_reference_t<decltype(o.*member)>;
            o.*member = static_cast<T>(v);
          }
        },
        field->second);
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

std::string BilinearSubjectModel::describe() const {
  return "bilinear model " + path + " (" + std::to_string(bilinear.id_knobs) + " x " +
         std::to_string(bilinear.exp_knobs) + " knobs, " +
         std::to_string(tracking.face.identity_count) + " identity modes)";
}

std::string BilinearSubjectModel::limitation() const {
  int named = 0;
  for (int row : tracking.expression_row) named += row >= 0 ? 1 : 0;
  const int shapes = static_cast<int>(tracking.expression_row.size());
  std::string note;
  if (named < shapes) {
    note = std::to_string(shapes - named) + " of the face model's " + std::to_string(shapes) +
           " fitting shapes are not in the model and keep the generic blendshapes";
  }
  if (bilinear.exp_knobs >= named) return note;
  // u_e - u_0 of `named` shapes in exp_knobs dimensions: the blendshapes are linearly dependent.
  return (note.empty() ? "" : note + "; ") + "the model keeps " +
         std::to_string(bilinear.exp_knobs) + " expression knobs for " + std::to_string(named) +
         " blendshapes, so the subject's blendshapes span only " +
         std::to_string(bilinear.exp_knobs) +
         " dimensions and the weights are not unique; for tracking, build it with "
         "`facebooth model build --exp-knobs " +
         std::to_string(bilinear.expression_count) + "`";
}

Result<std::unique_ptr<BilinearSubjectModel>> load_bilinear_subject_model(
    const std::string& path, const FaceModel& topology, const std::string& command) {
  std::cerr << command << ": loading the bilinear model " << path << "...\n";
  auto bytes = read_file_bytes(path);
  if (!bytes) {
    return fail(bytes.error().message +
                " (a bilinear model is written by `facebooth model build --out FILE`)");
  }
  auto parsed = parse_bilinear_model(std::as_bytes(std::span(*bytes)));
  if (!parsed) return fail(path + ": " + parsed.error().message);
  auto out = std::make_unique<BilinearSubjectModel>();
  out->path = path;
  out->bilinear = std::move(*parsed);
  auto tracking = make_bilinear_tracking_model(out->bilinear, topology);
  if (!tracking) return fail(path + ": " + tracking.error().message);
  out->tracking = std::move(*tracking);
  out->blendshapes.emplace(out->bilinear, out->tracking);
  if (const std::string note = out->limitation(); !note.empty())
    std::cerr << command << ": note: " << note << "\n";
  return out;
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
    if (run.tracker.report_weight_sigma)
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
