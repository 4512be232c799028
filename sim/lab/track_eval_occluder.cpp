// facebooth-lab eval track: the occluder takes, a flat plate passing in front of the face, each
// against a plate-free control take.
#include <algorithm>
#include <iostream>
#include <numeric>

#include "sim/lab/track_eval_parts.hpp"

namespace fb::cli::track_eval {

namespace {

// Recovery: frames after the plate leaves the face until the tracker is tracking again with
// the weight error back at its pre-occlusion level (frame MAE <= max(0.05, 1.5 x the mean
// before the plate)) and the pose within 1 deg / 2 mm of the truth (after the calibrated
// frame's constant offset, see score()).
int recovery_frames(const RenderedTake& take, const std::vector<FrameResult>& results, int k) {
  int recovery = -1;
  if (take.take.occluder_last >= 0) {
    double before = 0;
    int nb = 0;
    for (int f = 0; f < take.take.occluder_first; ++f) {
      const auto& r = results[static_cast<std::size_t>(f)];
      if (!r.calibrated || r.state == TrackState::kCalibrating) continue;
      before += std::accumulate(r.abs_error.begin(), r.abs_error.end(), 0.0) / k;
      ++nb;
    }
    const double limit = std::max(0.05, 1.5 * (nb ? before / nb : 0.0));
    const RigidPose gauge = calibration_gauge(results);
    const Eigen::Vector3d c = take.take.face_centre_model;
    for (int f = take.take.occluder_last + 1; f < static_cast<int>(results.size()); ++f) {
      const auto& r = results[static_cast<std::size_t>(f)];
      const double mae = std::accumulate(r.abs_error.begin(), r.abs_error.end(), 0.0) / k;
      const RigidPose aligned = compose(r.truth, gauge);
      if (tracked(r.state) && mae <= limit && rotation_error_deg(r.estimate, aligned) <= 1.0 &&
          (r.estimate.apply(c) - aligned.apply(c)).norm() <= 2.0) {
        recovery = f - take.take.occluder_last - 1;
        break;
      }
    }
  }
  return recovery;
}

}  // namespace

// One occluder take: a flat plate passes in front of the face. Landmarks are on: those under
// the plate are misdetected (moved onto it), as a real detector's would be, and the tracker
// must drop them itself. `run` gives the tracker options and whether the true identity is
// loaded instead of calibrated (both the take and its control). Appends the per-frame mean abs
// error of the shapes the plate does not cover to `unaffected`; returns the take's figures.
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
  const int recovery = recovery_frames(*otake, *ores, k);
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

// The `occluder` object of the report: every take, and how the worst frames spread.
nlohmann::json occluder_json(const nlohmann::json& occluder_takes,
                             const std::vector<double>& unaffected) {
  nlohmann::json occluder = {
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
    occluder["worst_frame_per_take"] = to_json(stats_of(worst));
    occluder["takes_over_0_05"] =
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
    occluder["unaffected_weight_error_by_unoccluded_shapes"] = by_count;
    occluder["frames_over_0_05"] = over;
  }
  return occluder;
}

}  // namespace fb::cli::track_eval
