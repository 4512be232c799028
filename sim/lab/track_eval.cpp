// facebooth-lab eval track: the real-time tracker (algo/tracking) scored against the ground truth
// of synthetic takes (synthetic_take.hpp): blendshape weights and head pose with landmarks and
// depth only, the same takes with the true identity loaded, and occluder takes whose plate
// passes in front of the face, each against a plate-free control. Landmarks come from the
// ground truth plus noise, or (--landmarks dlib) from dlib on the synthetic colour render; the
// JSON says which. One JSON object on stdout, progress on stderr.
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <iostream>
#include <nlohmann/json.hpp>
#include <numeric>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "sim/camera/world_presets.hpp"
#include "sim/scoring/occlusion_eval.hpp"
#include "sim/scoring/take_runner.hpp"
#include "sim/lab/lab_commands.hpp"
#include "sim/subject/unit_calibration.hpp"
#include "storage/asset_files.hpp"

namespace fb::cli {
namespace {

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

// Scores the frames after calibration (the subject's identity is known from then on).
struct Score {
  std::vector<double> weight_error;  // per frame: mean over all shapes
  std::vector<double> active_error;  // per frame: mean over the take's active shapes
  std::vector<double> rot, centre, origin, raw_rot, raw_centre, abs_rot, abs_centre;
  std::vector<double> per_shape_sum;
  int frames = 0, lost = 0;
};

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

// One scenario of the realistic world (world_presets.hpp) over seeds 1..N: the take's usual
// figures with landmarks and depth only, the neutral segment's weights (truth 0 there), the
// frames a hand hides >= 30 % of the face (FrameTruth::face_hidden_fraction) and whether the
// tracker reports them (occlusion_eval.hpp), and acquisition among nearer distractors. The
// depth-only run finds the face with `reacquire` (dlib on the colour image; null = depth
// alone) while it has none and while it calibrates, as `track` and the device do.
Result<nlohmann::json> evaluate_world(const FaceModel& model, const ArkitMapping& mapping,
                                      const TakeSpec& design, long long seeds,
                                      const std::string& world, const RunOptions& base,
                                      TrackLandmarkSource* dlib, TrackLandmarkSource* reacquire) {
  const int k = model.fitting_expression_count;
  Score with_landmarks, depth_only;
  OcclusionScore occlusion, depth_only_occlusion;
  AcquisitionScore acquisition, depth_only_acquisition;
  std::vector<double> neutral_mean, neutral_max, hidden_error;
  double worst_neutral = -1.0;
  std::string worst_neutral_shape;
  int hidden_frames = 0, hidden_lost = 0, never_calibrated = 0;
  for (long long seed = 1; seed <= seeds; ++seed) {
    TakeSpec spec = design;
    spec.seed = static_cast<std::uint64_t>(seed);
    spec.world = world == "baseline" ? "" : world;
    spec.color = dlib != nullptr || reacquire != nullptr;
    std::cerr << "eval track: scenario " << world << ", seed " << seed << ": rendering "
              << spec.frames << " frames...\n";
    auto take = render_take(model, spec);
    if (!take) return take.failure();
    for (TrackLandmarkSource* source : {dlib, reacquire}) {
      if (source == nullptr) continue;
      source->reset();
      source->set_calibration(take->calibration);
    }
    RunOptions run = base;
    run.landmarks = true;
    run.dlib = dlib;
    auto a = run_take(model, mapping, *take, run);
    if (!a) return a.failure();
    run.dlib = nullptr;
    run.landmarks = false;
    run.reacquire = reacquire;
    auto b = run_take(model, mapping, *take, run);
    if (!b) return b.failure();
    score(*take, *a, with_landmarks, k);
    score(*take, *b, depth_only, k);
    occlusion.add(*take, *a);
    depth_only_occlusion.add(*take, *b);
    acquisition.add(*take, *a);
    acquisition.add(*take, *b);
    depth_only_acquisition.add(*take, *b);
    bool calibrated = false;
    for (std::size_t f = 0; f < a->size(); ++f) {
      const FrameResult& r = (*a)[f];
      calibrated = calibrated || r.calibrated;
      if (!r.calibrated || r.state == TrackState::kCalibrating) continue;
      const auto& e = r.abs_error;
      if (static_cast<int>(f) < spec.neutral_frames) {
        neutral_mean.push_back(std::accumulate(e.begin(), e.begin() + k, 0.0) / k);
        const auto worst = std::max_element(e.begin(), e.begin() + k);
        neutral_max.push_back(*worst);
        if (*worst > worst_neutral) {
          worst_neutral = *worst;
          worst_neutral_shape = model.expression_names[static_cast<std::size_t>(worst - e.begin())];
        }
      }
      if (take->frames[f].truth.face_hidden_fraction >= 0.3) {
        ++hidden_frames;
        hidden_lost += tracked(r.state) ? 0 : 1;
        hidden_error.push_back(std::accumulate(e.begin(), e.begin() + k, 0.0) / k);
      }
    }
    never_calibrated += calibrated ? 0 : 1;
  }
  nlohmann::json j = score_json(with_landmarks, model);
  j["per_shape_mae"] = top_shapes(j["per_shape_mae"], 5);
  const nlohmann::json d = score_json(depth_only, model);
  // A run that never calibrated scores no frame: null, not 0.
  j["depth_only_frames_scored"] = d["frames_scored"];
  j["depth_only_weight_mae"] = depth_only.frames ? d["weight_mae"] : nlohmann::json(nullptr);
  if (!with_landmarks.frames) j["weight_mae"] = nullptr;
  j["depth_only_pose_error_deg"] = d["pose_error_deg"];
  j["depth_only_frames_lost"] = d["frames_lost"];
  j["takes"] = seeds;
  j["takes_never_calibrated"] = never_calibrated;
  j["neutral_weight_mean"] =
      neutral_mean.empty() ? nlohmann::json(nullptr) : nlohmann::json(stats_of(neutral_mean).mean);
  j["neutral_weight_max"] =
      neutral_max.empty() ? nlohmann::json(nullptr) : nlohmann::json(stats_of(neutral_max).max);
  j["neutral_weight_max_shape"] =
      neutral_max.empty() ? nlohmann::json(nullptr) : nlohmann::json(worst_neutral_shape);
  j["frames_face_hidden_30pct"] = hidden_frames;
  j["frames_lost_while_hidden"] = hidden_lost;
  j["weight_mae_while_hidden"] =
      hidden_error.empty() ? nlohmann::json(nullptr) : nlohmann::json(stats_of(hidden_error).mean);
  j.update(occlusion.json());
  const nlohmann::json depth_only_figures = depth_only_occlusion.json();
  for (const auto& [key, value] : depth_only_figures.items()) j["depth_only_" + key] = value;
  // Acquisition over both runs: the one with landmarks and the depth-only one (which finds
  // the face by detection, or with `reacquire` null by depth alone).
  j.update(acquisition.json());
  j["depth_only_acquired_with_nearer_distractors"] =
      depth_only_acquisition.json()["acquired_with_nearer_distractors"];
  return j;
}

// One occluder take: a flat plate passes in front of the face. Landmarks are on: those under
// the plate are misdetected (moved onto it), as a real detector's would be, and the tracker
// must drop them itself. `run` gives the tracker options and whether the true identity is
// loaded instead of calibrated (both the take and its control). Appends the per-frame mean abs
// error of the shapes the plate does not cover to `unaffected`; returns the take's figures.
constexpr int kOccluderTakeFrames = 130;

Result<nlohmann::json> evaluate_occluder_take(const FaceModel& model, const ArkitMapping& mapping,
                                              const RunOptions& run, const TakeSpec& spec,
                                              std::vector<double>& unaffected) {
  const int k = model.fitting_expression_count;
  const std::uint64_t seed = spec.seed;
  TakeSpec ospec = spec;
  ospec.frames = kOccluderTakeFrames;
  ospec.occluder = true;
  ospec.color = false;
  std::cerr << "eval track: occluder take " << seed << ": rendering " << ospec.frames
            << " frames...\n";
  auto otake = render_take(model, ospec);
  if (!otake) return otake.failure();
  RunOptions orun = run;
  orun.landmarks = true;
  orun.tracker.weights.report_weight_sigma = true;  // what each frame's data allows, see per_frame
  auto ores = run_take(model, mapping, *otake, orun);
  if (!ores) return ores.failure();
  // The control: the same take (motion, weights, landmark noise) without the plate, so the
  // plate's own effect on the shapes it does not cover can be told from how well those shapes
  // are tracked at all (a brow that moves while every landmark is dropped lags either way).
  TakeSpec cspec = ospec;
  cspec.occluder = false;
  std::cerr << "eval track: occluder take " << seed
            << ": rendering the control without the plate\n";
  auto ctake = render_take(model, cspec);
  if (!ctake) return ctake.failure();
  auto cres = run_take(model, mapping, *ctake, orun);
  if (!cres) return cres.failure();
  std::vector<double> added;  // per frame: unaffected error minus the control's on those shapes
  std::vector<double> occluded_err;
  const std::size_t first_frame = unaffected.size();
  nlohmann::json worst_unaffected = nlohmann::json::array();
  int lost_during = 0, misdetected = 0, used_during = 0;
  for (int f = otake->take.occluder_first; f >= 0 && f <= otake->take.occluder_last; ++f) {
    const auto& r = (*ores)[static_cast<std::size_t>(f)];
    const auto& tf = otake->frames[static_cast<std::size_t>(f)];
    if (!tracked(r.state)) ++lost_during;
    misdetected += tf.landmarks_misdetected;
    used_during += r.landmarks_used;
    const auto& control = (*cres)[static_cast<std::size_t>(f)];
    double sum = 0, osum = 0, csum = 0;
    int n = 0, on = 0;
    for (int j = 0; j < k; ++j) {
      if (tf.occluded_shapes[static_cast<std::size_t>(j)]) {
        osum += r.abs_error[static_cast<std::size_t>(j)];
        ++on;
      } else {
        sum += r.abs_error[static_cast<std::size_t>(j)];
        csum += control.abs_error[static_cast<std::size_t>(j)];
        ++n;
      }
    }
    if (n) unaffected.push_back(sum / n);  // the caller's, over all occluder takes
    if (n) added.push_back((sum - csum) / n);
    // The unoccluded shape with the largest error on this frame (diagnostics).
    int worst = -1;
    for (int j = 0; j < k; ++j) {
      if (tf.occluded_shapes[static_cast<std::size_t>(j)]) continue;
      if (worst < 0 ||
          r.abs_error[static_cast<std::size_t>(j)] > r.abs_error[static_cast<std::size_t>(worst)])
        worst = j;
    }
    if (worst >= 0) {
      const auto w = static_cast<std::size_t>(worst);
      worst_unaffected.push_back({{"frame", f},
                                  {"unaffected_mae", n ? sum / n : 0.0},
                                  {"occluded_shapes", on},
                                  {"unoccluded_shapes", n},
                                  {"worst_shape", model.expression_names[w]},
                                  {"worst_error", r.abs_error[w]},
                                  {"worst_shape_data_sigma", r.weight_sigma[w]},
                                  {"worst_error_in_control", control.abs_error[w]}});
    }
    if (on) occluded_err.push_back(osum / on);
  }
  // Recovery: frames after the plate leaves the face until the tracker is tracking again with
  // the weight error back at its pre-occlusion level (frame MAE <= max(0.05, 1.5 x the mean
  // before the plate)) and the pose within 1 deg / 2 mm of the truth (after the calibrated
  // frame's constant offset, see score()).
  int recovery = -1;
  if (otake->take.occluder_last >= 0) {
    double before = 0;
    int nb = 0;
    for (int f = 0; f < otake->take.occluder_first; ++f) {
      const auto& r = (*ores)[static_cast<std::size_t>(f)];
      if (!r.calibrated || r.state == TrackState::kCalibrating) continue;
      before += std::accumulate(r.abs_error.begin(), r.abs_error.end(), 0.0) / k;
      ++nb;
    }
    const double limit = std::max(0.05, 1.5 * (nb ? before / nb : 0.0));
    const RigidPose gauge = calibration_gauge(*ores);
    const Eigen::Vector3d c = otake->take.face_centre_model;
    for (int f = otake->take.occluder_last + 1; f < static_cast<int>(ores->size()); ++f) {
      const auto& r = (*ores)[static_cast<std::size_t>(f)];
      const double mae = std::accumulate(r.abs_error.begin(), r.abs_error.end(), 0.0) / k;
      const RigidPose aligned = compose(r.truth, gauge);
      if (tracked(r.state) && mae <= limit && rotation_error_deg(r.estimate, aligned) <= 1.0 &&
          (r.estimate.apply(c) - aligned.apply(c)).norm() <= 2.0) {
        recovery = f - otake->take.occluder_last - 1;
        break;
      }
    }
  }
  Score oscore;
  score(*otake, *ores, oscore, k);
  nlohmann::json active_names = nlohmann::json::array();
  for (int j : otake->take.active)
    active_names.push_back(model.expression_names[static_cast<std::size_t>(j)]);
  const std::vector<double> mine(unaffected.begin() + static_cast<std::ptrdiff_t>(first_frame),
                                 unaffected.end());
  std::cerr << "eval track: occluder take " << seed << ": unaffected weight error max "
            << stats_of(mine).max << ", recovery " << recovery << " frames\n";
  return nlohmann::json{
      {"seed", seed},
      {"active_shapes", active_names},
      {"frames_over_face", {otake->take.occluder_first, otake->take.occluder_last}},
      {"frames_lost_during_occlusion", lost_during},
      {"landmarks_misdetected", misdetected},
      {"landmarks_used_during_occlusion", used_during},
      {"occluded_unaffected_weight_error", stats_of(mine).max},
      {"unaffected_error_added_by_plate", stats_of(added).max},
      {"unaffected_error_added_by_plate_per_frame", to_json(stats_of(added))},
      {"unaffected_weight_error_per_frame", to_json(stats_of(mine))},
      {"occluded_shapes_weight_error_per_frame", to_json(stats_of(occluded_err))},
      {"occlusion_recovery_frames", recovery},
      {"per_frame", worst_unaffected},
      {"take", score_json(oscore, model)}};
}

int run_eval_track(const ParsedOptions& options) {
  auto overrides = tracker_overrides(options.get("set"));
  if (!overrides) return report_failure(overrides.error());
  auto seeds = options.get_int("seeds");
  auto frames = options.get_int("frames");
  auto active = options.get_int("active");
  auto occluder_seed = options.get_int("occluder-seed");
  auto occluder_takes_count = options.get_int("occluder-takes");
  if (!occluder_seed || *occluder_seed < 0 || !occluder_takes_count || *occluder_takes_count < 1)
    return report_failure(
        {"--occluder-seed must be a non-negative integer and --occluder-takes at least 1"});
  if (!seeds || !frames || !active)
    return report_failure({"--seeds, --frames, --active must be integers"});
  if (*seeds < 1 || *frames < 60 || *active < 1) {
    return report_failure({"need --seeds >= 1, --frames >= 60, --active >= 1"});
  }
  // The occluder takes' plate arrives at frame 60: the faces must move before it does.
  auto neutral = options.get_int("neutral-frames");
  if (!neutral || *neutral < 1 || *neutral > 50 || *neutral > *frames - 10) {
    return report_failure(
        {"--neutral-frames must be an integer from 1 to 50 and at most --frames - 10 (the "
         "takes' expressions start after it, and the occluder takes' plate arrives at frame 60)"});
  }
  const std::string occluder_identity = options.get("occluder-identity");
  if (occluder_identity != "calibrated" && occluder_identity != "known") {
    return report_failure(
        {"--occluder-identity must be calibrated (the tracker fits the subject, "
         "as on the device) or known (the true identity is loaded)"});
  }
  auto model_result = load_face_model();
  if (!model_result) return report_failure(model_result.error());
  const FaceModel& model = *model_result;
  auto mapping = make_arkit_mapping(model);
  if (!mapping) return report_failure(mapping.error());
  const int k = model.fitting_expression_count;
  // --model: the tracker calibrates with a bilinear model (the takes stay the face model's).
  std::unique_ptr<BilinearSubjectModel> bilinear;
  if (const std::string file = options.get("model"); !file.empty()) {
    if (occluder_identity == "known") {
      return report_failure(
          {"--occluder-identity known loads the face model's true identity; "
           "it cannot be combined with --model"});
    }
    auto loaded = load_bilinear_subject_model(file, model, "eval track");
    if (!loaded) return report_failure(loaded.error());
    bilinear = std::move(*loaded);
  }
  const FaceModel& tracker_model = bilinear ? bilinear->tracking.face : model;
  const std::string landmark_source = options.get("landmarks");
  if (landmark_source != "truth" && landmark_source != "dlib") {
    return report_failure({"--landmarks must be truth or dlib"});
  }
  std::optional<TrackLandmarkSource> dlib;
  long long dlib_frames = 0, dlib_found = 0, dlib_axes = 0;
  double dlib_sq_error = 0;

  // The take design both kinds of take share; each sets its seed (and the plain takes their
  // length, the occluder takes theirs).
  TakeSpec design;
  design.active_shapes = static_cast<int>(*active);
  design.neutral_frames = static_cast<int>(*neutral);
  auto unit_calibration = parse_unit_calibration(options.get("unit-calibration"));
  if (!unit_calibration) return report_failure(unit_calibration.error());
  design.unit_calibration = *unit_calibration;

  if (const std::string scenario = options.get("scenario"); !scenario.empty()) {
    // The realistic world: each part (and, for realistic, a plain baseline) then the scenario;
    // only the plain and depth-only runs (no known-identity or occluder takes).
    SyntheticOptions probe;
    if (auto ok = apply_world_preset(scenario, 1, probe); !ok) return report_failure(ok.error());
    std::vector<std::string> parts;
    if (scenario == "realistic") {
      parts.push_back("baseline");
      for (const auto& p : world_parts()) parts.push_back(p);
    }
    parts.push_back(scenario);
    design.frames = static_cast<int>(*frames);
    if (landmark_source == "dlib") {
      auto detector = load_landmark_detector(options.get("shape-predictor"));
      if (!detector) return report_failure(detector.error());
      dlib.emplace(std::move(*detector), KinectCalibration::defaults());
    }
    // The depth-only runs find the face by detection, as `track` and the device do; without
    // the shape predictor, by depth alone (the JSON says which).
    std::optional<TrackLandmarkSource> reacquire;
    std::string reacquire_note = "dlib detection on the colour image, then depth";
    if (auto detector = load_landmark_detector(options.get("shape-predictor")); detector) {
      reacquire.emplace(std::move(*detector), KinectCalibration::defaults());
    } else {
      reacquire_note = "depth only (" + detector.error().message + ")";
      std::cerr << "eval track: " << reacquire_note << "\n";
    }
    TrackLandmarkSource* const reacquire_source = reacquire ? &*reacquire : nullptr;
    RunOptions base;
    base.tracker = *overrides;
    base.bilinear = bilinear.get();
    nlohmann::json scenarios, out;
    for (const auto& part : parts) {
      auto j = evaluate_world(model, *mapping, design, *seeds, part, base, dlib ? &*dlib : nullptr,
                              reacquire_source);
      if (!j) return report_failure(j.error());
      if (decalibrates_unit(part) && design.unit_calibration == UnitCalibration::kSelfCalibrated) {
        // The same run with the depth law known (registration self-calibrated), and on the
        // unit calibrated perfectly: the reference self-calibration is held to.
        for (const auto mode : {UnitCalibration::kSelfWithDepthLaw, UnitCalibration::kCalibrated}) {
          TakeSpec other = design;
          other.unit_calibration = mode;
          auto c = evaluate_world(model, *mapping, other, *seeds, part, base,
                                  dlib ? &*dlib : nullptr, reacquire_source);
          if (!c) return report_failure(c.error());
          (*j)[std::string("unit_") + unit_calibration_name(mode)] = std::move(*c);
        }
        const nlohmann::json& reference = (*j)["unit_calibrated"];
        nlohmann::json ratio;
        for (const auto& [name, figures] :
             {std::pair<std::string, const nlohmann::json*>{"self", &*j},
              {"self-depth-law", &(*j)["unit_self-depth-law"]}})
          ratio[name] = {
              {"weight_mae", ratio_of((*figures)["weight_mae"], reference["weight_mae"])},
              {"depth_only_weight_mae",
               ratio_of((*figures)["depth_only_weight_mae"], reference["depth_only_weight_mae"])}};
        (*j)["decalibrated_vs_calibrated_ratio"] = ratio;
      }
      if (part == scenario) out = *j;
      scenarios[part] = std::move(*j);
    }
    out["scenario"] = scenario;
    out["scenarios"] = scenarios;
    out["unit_calibration"] = unit_calibration_name(design.unit_calibration);
    out["landmark_source"] = landmark_source;
    out["setup"] = {{"seeds", *seeds},
                    {"frames_per_take", *frames},
                    {"neutral_weight", "over the neutral frames after calibration (truth 0)"},
                    {"frames_face_hidden_30pct", "frames a hand hides >= 30 % of the face"},
                    {"depth_only_reacquire", reacquire_note}};
    out["setup"].update(occlusion_setup_notes());
    std::cout << out.dump(2) << std::endl;
    return kExitOk;
  }

  Score with_landmarks, depth_only, known;
  nlohmann::json takes = nlohmann::json::array();
  PinholeIntrinsics intrinsics;
  for (long long seed = 1; seed <= *seeds; ++seed) {
    TakeSpec spec = design;
    spec.seed = static_cast<std::uint64_t>(seed);
    spec.frames = static_cast<int>(*frames);
    spec.color = landmark_source == "dlib";
    std::cerr << "eval track: seed " << seed << ": rendering " << spec.frames << " frames...\n";
    auto take = render_take(model, spec);
    if (!take) return report_failure(take.error());
    intrinsics = take->intrinsics;
    if (landmark_source == "dlib" && !dlib) {
      auto detector = load_landmark_detector(options.get("shape-predictor"));
      if (!detector) return report_failure(detector.error());
      dlib.emplace(std::move(*detector), take->calibration);
    }
    if (dlib) dlib->reset();
    RunOptions run;
    run.tracker = *overrides;
    run.landmarks = true;
    run.dlib = dlib ? &*dlib : nullptr;
    run.bilinear = bilinear.get();
    std::vector<float> calibrated_identity;
    run.identity_out = &calibrated_identity;
    auto a = run_take(model, *mapping, *take, run);
    if (!a) return report_failure(a.error());
    run.identity_out = nullptr;
    const auto [offset_deg, offset_mm] =
        identity_rigid_offset(model, take->frames[0].truth.identity_coeffs, tracker_model,
                              calibrated_identity, take->take.face_centre_model);
    const RigidPose gauge = calibration_gauge(*a);
    const double gauge_deg = Eigen::AngleAxisd(gauge.rotation).angle() * kDeg;
    const double gauge_mm =
        (gauge.apply(take->take.face_centre_model) - take->take.face_centre_model).norm();
    for (const auto& r : *a) {
      dlib_frames += dlib ? 1 : 0;
      dlib_found += r.detected ? 1 : 0;
      dlib_sq_error += r.landmark_sq_error_px2;
      dlib_axes += r.landmark_axes;
    }
    run.dlib = nullptr;
    run.landmarks = false;
    auto b = run_take(model, *mapping, *take, run);
    if (!b) return report_failure(b.error());
    run.landmarks = true;
    run.known_identity = true;  // the face model's true identity (the reference for the solve)
    run.bilinear = nullptr;
    auto c = run_take(model, *mapping, *take, run);
    if (!c) return report_failure(c.error());
    score(*take, *c, known, k);
    Score sa, sb;
    score(*take, *a, sa, k);
    score(*take, *b, sb, k);
    score(*take, *a, with_landmarks, k);
    score(*take, *b, depth_only, k);
    nlohmann::json active_names = nlohmann::json::array();
    for (int j : take->take.active)
      active_names.push_back(model.expression_names[static_cast<std::size_t>(j)]);
    takes.push_back({{"seed", seed},
                     {"active_shapes", active_names},
                     {"weight_mae", stats_of(sa.weight_error).mean},
                     {"weight_mae_active_shapes", stats_of(sa.active_error).mean},
                     {"pose_error_deg", stats_of(sa.rot).mean},
                     {"pose_error_mm", stats_of(sa.centre).mean},
                     {"absolute_pose_error_deg", stats_of(sa.abs_rot).mean},
                     {"absolute_pose_error_mm", stats_of(sa.abs_centre).mean},
                     {"constant_pose_offset_deg", gauge_deg},
                     {"constant_pose_offset_mm", gauge_mm},
                     {"identity_rigid_offset_deg", offset_deg},
                     {"identity_rigid_offset_mm", offset_mm},
                     {"frames_lost", sa.lost},
                     {"depth_only_weight_mae", stats_of(sb.weight_error).mean},
                     {"depth_only_pose_error_deg", stats_of(sb.rot).mean},
                     {"depth_only_pose_error_mm", stats_of(sb.centre).mean}});
    std::cerr << "eval track: seed " << seed << ": weight MAE " << stats_of(sa.weight_error).mean
              << " (depth only " << stats_of(sb.weight_error).mean << "), pose "
              << stats_of(sa.rot).mean << " deg " << stats_of(sa.centre).mean << " mm\n";
  }

  // Occluder takes (seeds occluder_seed ..): the figure is the worst frame of all of them.
  std::vector<double> unaffected;
  nlohmann::json occluder_takes = nlohmann::json::array();
  int recovery = 0;
  RunOptions occluder_run;
  occluder_run.tracker = *overrides;
  occluder_run.known_identity = occluder_identity == "known";
  occluder_run.bilinear = bilinear.get();
  for (long long i = 0; i < *occluder_takes_count; ++i) {
    TakeSpec ospec = design;
    ospec.seed = static_cast<std::uint64_t>(*occluder_seed + i);
    auto take = evaluate_occluder_take(model, *mapping, occluder_run, ospec, unaffected);
    if (!take) return report_failure(take.error());
    const int r = (*take)["occlusion_recovery_frames"];
    recovery = (r < 0 || recovery < 0) ? -1 : std::max(recovery, r);
    occluder_takes.push_back(std::move(*take));
  }

  nlohmann::json result;
  const nlohmann::json wl = score_json(with_landmarks, model);
  const nlohmann::json dl = score_json(depth_only, model);
  result["weight_mae"] = wl["weight_mae"];
  result["weight_mae_active_shapes"] = wl["weight_mae_active_shapes"];
  result["pose_error_deg"] = wl["pose_error_deg"];
  result["pose_error_mm"] = wl["pose_error_mm"];
  result["occluded_unaffected_weight_error"] = stats_of(unaffected).max;
  result["occluded_unaffected_weight_error_mean"] = stats_of(unaffected).mean;
  // The plate's own effect: the same error minus the control take's (no plate) on the same
  // shapes and frames, the worst frame of all takes.
  double added_max = -1.0;
  for (const auto& t : occluder_takes)
    added_max = std::max(added_max, t["unaffected_error_added_by_plate"].get<double>());
  result["occluded_unaffected_error_added_by_plate"] = added_max;
  result["occlusion_recovery_frames"] = recovery;
  result["absolute_pose_error_deg"] = wl["absolute_pose_error_deg"];
  result["absolute_pose_error_mm"] = wl["absolute_pose_error_mm"];
  result["with_landmarks"] = wl;
  result["known_identity"] = score_json(known, model);
  result["subject_model"] = bilinear ? bilinear->describe() : "face model identity PCA";
  if (const std::string note = bilinear ? bilinear->limitation() : ""; !note.empty())
    result["subject_model_limitation"] = note;
  result["depth_only"] = dl;
  result["occluder"] = {
      {"takes", occluder_takes},
      {"frames_per_take", kOccluderTakeFrames},
      {"plate_mm", {90, 110}},
      {"plate_in_front_of_mouth_mm", 110},
      {"landmarks",
       "truth + 1.5 px noise; those under the plate misdetected (moved 15 px onto it)"},
      {"unaffected_weight_error_per_frame", to_json(stats_of(unaffected))}};
  {
    // The figure is the worst frame of a few takes, so how it spreads over takes says more
    // than one value (e.g. --occluder-seed 1010 --occluder-takes 20).
    std::vector<double> worst;
    for (const auto& t : occluder_takes)
      worst.push_back(t["occluded_unaffected_weight_error"].get<double>());
    result["occluder"]["worst_frame_per_take"] = to_json(stats_of(worst));
    result["occluder"]["takes_over_0_05"] =
        std::count_if(worst.begin(), worst.end(), [](double e) { return e > 0.05; });
    // Where the misses are: the figure is a mean over the shapes the plate leaves uncovered,
    // so on a frame that covers all but one or two it is that one shape's error, and a weak
    // shape (a brow) alone has a per-frame standard error from depth of ~0.1
    // (worst_shape_data_sigma). Split by how many shapes the mean is over, and every frame
    // over 0.05 with what its data allowed.
    std::vector<double> one_or_two, three_or_more;
    nlohmann::json over = nlohmann::json::array();
    for (const auto& t : occluder_takes)
      for (const auto& f : t["per_frame"]) {
        const double e = f["unaffected_mae"].get<double>();
        (f["unoccluded_shapes"].get<int>() <= 2 ? one_or_two : three_or_more).push_back(e);
        if (e > 0.05) {
          nlohmann::json entry = f;
          entry["take"] = t["seed"];
          over.push_back(std::move(entry));
        }
      }
    auto split = [](const std::vector<double>& errors) {
      return nlohmann::json{{"frames", errors.size()},
                            {"max", stats_of(errors).max},
                            {"frames_over_0_05", std::count_if(errors.begin(), errors.end(),
                                                               [](double e) { return e > 0.05; })}};
    };
    const nlohmann::json by_count = {{"1_to_2", split(one_or_two)},
                                     {"3_or_more", split(three_or_more)}};
    result["occluder"]["unaffected_weight_error_by_unoccluded_shapes"] = by_count;
    result["occluder"]["frames_over_0_05"] = over;
  }
  result["takes"] = takes;
  result["tracker_overrides"] = options.get("set");
  result["landmark_source"] = landmark_source;
  if (dlib) {
    result["dlib_detection_rate"] = dlib_frames ? double(dlib_found) / dlib_frames : 0.0;
    result["dlib_landmark_error_px"] = dlib_axes ? std::sqrt(dlib_sq_error / dlib_axes) : 0.0;
  }
  if (auto t = FaceTracker::create(model, intrinsics, *overrides); t) {
    nlohmann::json weak = nlohmann::json::array();
    for (int j : (*t)->weak_shapes())
      weak.push_back(model.expression_names[static_cast<std::size_t>(j)]);
    result["weakly_observed_shapes"] = weak;
    result["samples"] = (*t)->sample_count();
  }
  result["setup"] = {
      {"seeds", *seeds},
      {"frames_per_take", *frames},
      {"active_shapes_per_take", *active},
      {"neutral_frames", *neutral},
      {"occluder_identity", occluder_identity},
      {"scored_frames", "after identity calibration (first 10 tracked frames, neutral face)"},
      {"weight_mae",
       "mean over frames of the mean abs error over all 53 model fitting shapes, "
       "with landmarks; weight_mae_active_shapes: over the animated shapes only"},
      {"pose_error_deg",
       "mean rotation error of the filtered (streamed) pose, after removing "
       "the constant rigid offset between the calibrated and the true model "
       "frame (an identity's rigid part, unobservable from depth; see "
       "absolute_pose_error_* and known_identity for absolute errors)"},
      {"pose_error_mm",
       "mean position error of the face centre (68-landmark centroid of the "
       "true identity), same alignment"},
      {"known_identity",
       "the same takes with the true identity loaded (set_identity) instead "
       "of calibrated: absolute pose errors are meaningful there"},
      {"landmarks",
       "--landmarks truth (default): ground-truth 2D landmarks + N(0, 1.5 px) noise; "
       "--landmarks dlib: dlib HOG + shape_predictor_68 on the synthetic colour render, "
       "mapped into the depth image (known_identity still uses truth); contour points 0-16 "
       "unused; dlib_landmark_error_px: its rms error per image axis against the truth"},
      {"head_motion",
       "yaw 20 deg, pitch 10 deg, roll 5 deg, 20/10/30 mm sinusoids, 3-5.5 s periods"},
      {"sensor", "Kinect v1 model, noise on, 700 mm"},
      {"occluded_unaffected_weight_error",
       "max over the frames of all occluder takes with the plate over the face of the mean "
       "abs error of the shapes whose region it does not cover (landmarks on, those under the "
       "plate misdetected)"},
      {"occluded_unaffected_error_added_by_plate",
       "the same, minus the error of the same shapes on the same frame of a control take "
       "(same seed, motion, weights, no plate): what the plate itself adds"},
      {"occluder_frames_over_0_05",
       "occluder.frames_over_0_05 lists every such frame, with how many shapes the mean is "
       "over, its worst shape's error, that shape's error on the control take, and "
       "worst_shape_data_sigma: the standard error that frame's data alone (depth rows and "
       "landmarks, no priors) allows that weight; "
       "occluder.unaffected_weight_error_by_unoccluded_shapes splits the frames by that count"},
      {"occlusion_recovery_frames",
       "frames after the plate leaves until tracking with every "
       "weight within 0.1 and pose within 1 deg / 2 mm (-1 = never)"}};
  std::cout << result.dump(2) << std::endl;
  return kExitOk;
}

}  // namespace

Command eval_track_command() {
  return {
      {"eval track",
       "tracking accuracy on synthetic takes with ground truth (weights, pose, occluder)",
       "Prints one JSON object: weight_mae, pose_error_deg, pose_error_mm (with landmarks), the "
       "same depth-only, occluded_unaffected_weight_error, occlusion_recovery_frames, per take "
       "and per shape figures. Landmarks are ground truth + 1.5 px noise.",
       {{"seeds", "N", "synthetic takes (seeds 1..N)", "5"},
        {"frames", "N", "frames per take", "150"},
        {"active", "N", "animated shapes per take", "5"},
        {"neutral-frames", "N",
         "frames each take (and occluder take) holds a neutral face before its expressions "
         "start: the calibration window",
         "20"},
        {"occluder-seed", "N", "seed of the first occluder take", "1000"},
        {"occluder-takes", "N", "occluder takes (seeds occluder-seed ..)", "5"},
        {"occluder-identity", "calibrated|known",
         "the occluder takes' subject: calibrated by the tracker (as on the device), or the "
         "true identity loaded (tells calibration error from the solve's own)",
         "calibrated"},
        {"model", "FILE",
         "calibrate with this bilinear model (`facebooth model build`) and track with the "
         "subject's own blendshapes from it, instead of the face model's identity PCA",
         ""},
        {"landmarks", "truth|dlib",
         "landmarks of the with-landmarks runs: ground truth + 1.5 px noise, or dlib on the "
         "synthetic colour render",
         "truth"},
        {"shape-predictor", "PATH", "dlib 68-point model (--landmarks dlib)", kShapePredictor},
        {"set", "K=V,...", "tracker option overrides for tuning (e.g. temporal_frames=1)", ""},
        {"scenario", "NAME",
         "realistic (a baseline, every part alone, then all: JSON scenarios.<part>) or one "
         "part: identity|texture|hair|clutter|noise|unit (world_presets.hpp); empty = plain",
         ""},
        {"unit-calibration", "self|self-depth-law|reported|calibrated", kUnitCalibrationHelp,
         "self"},
        {"json", "", "print JSON (the only output format; accepted for symmetry)", ""}}},
      run_eval_track};
}

}  // namespace fb::cli
