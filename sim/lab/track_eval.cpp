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

#include "sim/lab/lab_commands.hpp"
#include "sim/lab/track_eval_parts.hpp"
#include "sim/scoring/take_runner.hpp"
#include "sim/subject/unit_calibration.hpp"
#include "storage/asset_files.hpp"

namespace fb::cli {
namespace {

using namespace track_eval;

// The options of eval track that need no face model, checked.
struct EvalTrackOptions {
  TrackerOptions overrides;
  long long seeds = 0, frames = 0, active = 0, neutral = 0;
  long long occluder_seed = 0, occluder_takes = 0;
  std::string occluder_identity;
};

Result<EvalTrackOptions> parse_eval_track(const ParsedOptions& options) {
  EvalTrackOptions o;
  auto overrides = tracker_overrides(options.get("set"));
  if (!overrides) return overrides.failure();
  o.overrides = *overrides;
  auto seeds = options.get_int("seeds");
  auto frames = options.get_int("frames");
  auto active = options.get_int("active");
  auto occluder_seed = options.get_int("occluder-seed");
  auto occluder_takes_count = options.get_int("occluder-takes");
  if (!occluder_seed || *occluder_seed < 0 || !occluder_takes_count || *occluder_takes_count < 1)
    return fail("--occluder-seed must be a non-negative integer and --occluder-takes at least 1");
  if (!seeds || !frames || !active) return fail("--seeds, --frames, --active must be integers");
  if (*seeds < 1 || *frames < 60 || *active < 1) {
    return fail("need --seeds >= 1, --frames >= 60, --active >= 1");
  }
  // The occluder takes' plate arrives at frame 60: the faces must move before it does.
  auto neutral = options.get_int("neutral-frames");
  if (!neutral || *neutral < 1 || *neutral > 50 || *neutral > *frames - 10) {
    return fail(
        "--neutral-frames must be an integer from 1 to 50 and at most --frames - 10 (the "
        "takes' expressions start after it, and the occluder takes' plate arrives at frame 60)");
  }
  o.occluder_identity = options.get("occluder-identity");
  if (o.occluder_identity != "calibrated" && o.occluder_identity != "known") {
    return fail(
        "--occluder-identity must be calibrated (the tracker fits the subject, "
        "as on the device) or known (the true identity is loaded)");
  }
  o.seeds = *seeds;
  o.frames = *frames;
  o.active = *active;
  o.neutral = *neutral;
  o.occluder_seed = *occluder_seed;
  o.occluder_takes = *occluder_takes_count;
  return o;
}

// What the plain takes (seeds 1..N) add up to: the three runs' scores, one entry per take, and
// dlib's detection figures when it gives the landmarks.
struct PlainTakes {
  Score with_landmarks, depth_only, known;
  nlohmann::json takes = nlohmann::json::array();
  PinholeIntrinsics intrinsics;
  std::optional<TrackLandmarkSource> dlib;
  long long dlib_frames = 0, dlib_found = 0, dlib_axes = 0;
  double dlib_sq_error = 0;
};

// Each plain take with landmarks (truth or dlib), depth only, and the true identity loaded.
Result<void> run_plain_takes(const ParsedOptions& options, const FaceModel& model,
                             const ArkitMapping& mapping, const FaceModel& tracker_model,
                             const EvalTrackOptions& o, const TakeSpec& design,
                             BilinearSubjectModel* bilinear, const std::string& landmark_source,
                             PlainTakes& p) {
  const int k = model.fitting_expression_count;
  for (long long seed = 1; seed <= o.seeds; ++seed) {
    TakeSpec spec = design;
    spec.seed = static_cast<std::uint64_t>(seed);
    spec.frames = static_cast<int>(o.frames);
    spec.color = landmark_source == "dlib";
    std::cerr << "eval track: seed " << seed << ": rendering " << spec.frames << " frames...\n";
    auto take = render_take(model, spec);
    if (!take) return take.failure();
    p.intrinsics = take->intrinsics;
    if (landmark_source == "dlib" && !p.dlib) {
      auto detector = load_landmark_detector(options.get("shape-predictor"));
      if (!detector) return detector.failure();
      p.dlib.emplace(std::move(*detector), take->calibration);
    }
    if (p.dlib) p.dlib->reset();
    RunOptions run;
    run.tracker = o.overrides;
    run.landmarks = true;
    run.dlib = p.dlib ? &*p.dlib : nullptr;
    run.bilinear = bilinear;
    std::vector<float> calibrated_identity;
    run.identity_out = &calibrated_identity;
    auto a = run_take(model, mapping, *take, run);
    if (!a) return a.failure();
    run.identity_out = nullptr;
    const auto [offset_deg, offset_mm] =
        identity_rigid_offset(model, take->frames[0].truth.identity_coeffs, tracker_model,
                              calibrated_identity, take->take.face_centre_model);
    const RigidPose gauge = calibration_gauge(*a);
    const double gauge_deg = Eigen::AngleAxisd(gauge.rotation).angle() * kDeg;
    const double gauge_mm =
        (gauge.apply(take->take.face_centre_model) - take->take.face_centre_model).norm();
    for (const auto& r : *a) {
      p.dlib_frames += p.dlib ? 1 : 0;
      p.dlib_found += r.detected ? 1 : 0;
      p.dlib_sq_error += r.landmark_sq_error_px2;
      p.dlib_axes += r.landmark_axes;
    }
    run.dlib = nullptr;
    run.landmarks = false;
    auto b = run_take(model, mapping, *take, run);
    if (!b) return b.failure();
    run.landmarks = true;
    run.known_identity = true;  // the face model's true identity (the reference for the solve)
    run.bilinear = nullptr;
    auto c = run_take(model, mapping, *take, run);
    if (!c) return c.failure();
    score(*take, *c, p.known, k);
    Score sa, sb;
    score(*take, *a, sa, k);
    score(*take, *b, sb, k);
    score(*take, *a, p.with_landmarks, k);
    score(*take, *b, p.depth_only, k);
    nlohmann::json active_names = nlohmann::json::array();
    for (int j : take->take.active)
      active_names.push_back(model.expression_names[static_cast<std::size_t>(j)]);
    p.takes.push_back({{"seed", seed},
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
  return success();
}

// The notes of the report's `setup` object: what each figure means.
nlohmann::json setup_json(const EvalTrackOptions& o) {
  return {{"seeds", o.seeds},
          {"frames_per_take", o.frames},
          {"active_shapes_per_take", o.active},
          {"neutral_frames", o.neutral},
          {"occluder_identity", o.occluder_identity},
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
}

int run_eval_track(const ParsedOptions& options) {
  auto parsed = parse_eval_track(options);
  if (!parsed) return report_failure(parsed.error());
  const EvalTrackOptions& o = *parsed;
  auto model_result = load_face_model();
  if (!model_result) return report_failure(model_result.error());
  const FaceModel& model = *model_result;
  auto mapping = make_arkit_mapping(model);
  if (!mapping) return report_failure(mapping.error());
  // --model: the tracker calibrates with a bilinear model (the takes stay the face model's).
  std::unique_ptr<BilinearSubjectModel> bilinear;
  if (const std::string file = options.get("model"); !file.empty()) {
    if (o.occluder_identity == "known") {
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

  // The take design both kinds of take share; each sets its seed (and the plain takes their
  // length, the occluder takes theirs).
  TakeSpec design;
  design.active_shapes = static_cast<int>(o.active);
  design.neutral_frames = static_cast<int>(o.neutral);
  auto unit_calibration = parse_unit_calibration(options.get("unit-calibration"));
  if (!unit_calibration) return report_failure(unit_calibration.error());
  design.unit_calibration = *unit_calibration;

  if (const std::string scenario = options.get("scenario"); !scenario.empty()) {
    return run_world_scenarios(options, model, *mapping, design, scenario, o.seeds, o.frames,
                               o.overrides, bilinear.get(), landmark_source);
  }

  PlainTakes plain;
  if (auto ok = run_plain_takes(options, model, *mapping, tracker_model, o, design, bilinear.get(),
                                landmark_source, plain);
      !ok) {
    return report_failure(ok.error());
  }

  // Occluder takes (seeds occluder_seed ..): the figure is the worst frame of all of them.
  std::vector<double> unaffected;
  nlohmann::json occluder_takes = nlohmann::json::array();
  int recovery = 0;
  RunOptions occluder_run;
  occluder_run.tracker = o.overrides;
  occluder_run.known_identity = o.occluder_identity == "known";
  occluder_run.bilinear = bilinear.get();
  for (long long i = 0; i < o.occluder_takes; ++i) {
    TakeSpec ospec = design;
    ospec.seed = static_cast<std::uint64_t>(o.occluder_seed + i);
    auto take = evaluate_occluder_take(model, *mapping, occluder_run, ospec, unaffected);
    if (!take) return report_failure(take.error());
    const int r = (*take)["occlusion_recovery_frames"];
    recovery = (r < 0 || recovery < 0) ? -1 : std::max(recovery, r);
    occluder_takes.push_back(std::move(*take));
  }

  nlohmann::json result;
  const nlohmann::json wl = score_json(plain.with_landmarks, model);
  const nlohmann::json dl = score_json(plain.depth_only, model);
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
  result["known_identity"] = score_json(plain.known, model);
  result["subject_model"] = bilinear ? bilinear->describe() : "face model identity PCA";
  if (const std::string note = bilinear ? bilinear->limitation() : ""; !note.empty())
    result["subject_model_limitation"] = note;
  result["depth_only"] = dl;
  result["occluder"] = occluder_json(occluder_takes, unaffected);
  result["takes"] = plain.takes;
  result["tracker_overrides"] = options.get("set");
  result["landmark_source"] = landmark_source;
  if (plain.dlib) {
    result["dlib_detection_rate"] =
        plain.dlib_frames ? double(plain.dlib_found) / plain.dlib_frames : 0.0;
    result["dlib_landmark_error_px"] =
        plain.dlib_axes ? std::sqrt(plain.dlib_sq_error / plain.dlib_axes) : 0.0;
  }
  if (auto t = FaceTracker::create(model, plain.intrinsics, o.overrides); t) {
    nlohmann::json weak = nlohmann::json::array();
    for (int j : (*t)->weak_shapes())
      weak.push_back(model.expression_names[static_cast<std::size_t>(j)]);
    result["weakly_observed_shapes"] = weak;
    result["samples"] = (*t)->sample_count();
  }
  result["setup"] = setup_json(o);
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
