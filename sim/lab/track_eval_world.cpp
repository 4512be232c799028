// facebooth-lab eval track --scenario: the tracker on the realistic world's parts
// (world_presets.hpp), with landmarks and depth only, against a plain baseline.
#include <algorithm>
#include <iostream>
#include <numeric>
#include <optional>

#include "sim/camera/world_presets.hpp"
#include "sim/lab/track_eval_parts.hpp"
#include "sim/scoring/occlusion_eval.hpp"
#include "sim/subject/unit_calibration.hpp"

namespace fb::cli::track_eval {
namespace {

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

}  // namespace

int run_world_scenarios(const ParsedOptions& options, const FaceModel& model,
                        const ArkitMapping& mapping, const TakeSpec& design_in,
                        const std::string& scenario, long long seeds, long long frames,
                        const TrackerOptions& overrides, BilinearSubjectModel* bilinear,
                        const std::string& landmark_source) {
  TakeSpec design = design_in;
  // The realistic world: each part (and, for realistic, a plain baseline) then the scenario;
  // only the plain and depth-only runs (no known-identity or occluder takes).
  auto parts = scenario_parts(scenario);
  if (!parts) return report_failure(parts.error());
  design.frames = static_cast<int>(frames);
  std::optional<TrackLandmarkSource> dlib;
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
  base.tracker = overrides;
  base.bilinear = bilinear;
  nlohmann::json scenarios, out;
  for (const auto& part : *parts) {
    auto j = evaluate_world(model, mapping, design, seeds, part, base, dlib ? &*dlib : nullptr,
                            reacquire_source);
    if (!j) return report_failure(j.error());
    if (decalibrates_unit(part) && design.unit_calibration == UnitCalibration::kSelfCalibrated) {
      // The same run with the depth law known (registration self-calibrated), and on the
      // unit calibrated perfectly: the reference self-calibration is held to.
      for (const auto mode : {UnitCalibration::kSelfWithDepthLaw, UnitCalibration::kCalibrated}) {
        TakeSpec other = design;
        other.unit_calibration = mode;
        auto c = evaluate_world(model, mapping, other, seeds, part, base, dlib ? &*dlib : nullptr,
                                reacquire_source);
        if (!c) return report_failure(c.error());
        (*j)[std::string("unit_") + unit_calibration_name(mode)] = std::move(*c);
      }
      const nlohmann::json& reference = (*j)["unit_calibrated"];
      nlohmann::json ratio;
      for (const auto& [name, figures] :
           {std::pair<std::string, const nlohmann::json*>{"self", &*j},
            {"self-depth-law", &(*j)["unit_self-depth-law"]}})
        ratio[name] = {{"weight_mae", ratio_of((*figures)["weight_mae"], reference["weight_mae"])},
                       {"depth_only_weight_mae", ratio_of((*figures)["depth_only_weight_mae"],
                                                          reference["depth_only_weight_mae"])}};
      (*j)["decalibrated_vs_calibrated_ratio"] = ratio;
    }
    if (part == scenario) out = *j;
    scenarios[part] = std::move(*j);
  }
  out["scenario"] = scenario;
  out["scenarios"] = scenarios;
  out["unit_calibration"] = unit_calibration_name(design.unit_calibration);
  out["landmark_source"] = landmark_source;
  out["setup"] = {{"seeds", seeds},
                  {"frames_per_take", frames},
                  {"neutral_weight", "over the neutral frames after calibration (truth 0)"},
                  {"frames_face_hidden_30pct", "frames a hand hides >= 30 % of the face"},
                  {"depth_only_reacquire", reacquire_note}};
  out["setup"].update(occlusion_setup_notes());
  std::cout << out.dump(2) << std::endl;
  return kExitOk;
}

}  // namespace fb::cli::track_eval
