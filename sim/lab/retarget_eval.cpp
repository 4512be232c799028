// facebooth-lab eval retarget: a stored take of synthetic subject A driving subject B's rig, as
// `facebooth retarget` does it (host/cli/retarget.hpp), against B's own truth for the same
// recipe (sim/subject/retarget_case.hpp), in a real SQLite session store.
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <iostream>

#include <nlohmann/json.hpp>

#include "algo/tracking/face_tracker.hpp"
#include "host/cli/retarget.hpp"
#include "host/cli/stats.hpp"
#include "sim/lab/transfer_image_lab.hpp"
#include "sim/subject/retarget_case.hpp"
#include "sim/subject/synthetic_take.hpp"
#include "storage/asset_files.hpp"

namespace fb::cli {

namespace {

namespace fs = std::filesystem;

struct Scored {
  Summary moving;
  double all_mean = 0;
  int frames = 0, driven = 0, shapes = 0, curves = 0;
};

// `c`'s take retargeted onto B through the store, as `facebooth retarget` does, against B's
// truth: distances over the vertices the truth moves >= min_motion from B's neutral.
Result<Scored> score(const fs::path& dir, const FaceModel& model, const RetargetCase& c,
                     double min_motion) {
  StoreOptions so;
  so.read_only = true;
  so.create = false;
  auto store = SessionStore::open(dir, so);
  if (!store) return store.failure();
  auto take = store->read_take(c.take);
  if (!take) return take.failure();
  auto target = rig_for_target(*store, "subject:" + std::to_string(c.target));
  if (!target) return target.failure();
  auto rig = store->read_rig(target->id);
  if (!rig) return rig.failure();
  auto columns = take_columns_for_rig(take->info.shape_names, rig->shape_names);
  if (!columns) return columns.failure();
  std::vector<double> moving, all;
  for (int f = 0; f < take->info.frame_count; ++f) {
    const auto out = retarget_frame(*take, f, *rig, *columns);
    const auto truth = retarget_truth(c, model, f);
    for (std::size_t v = 0; v + 2 < truth.size(); v += 3) {
      double motion = 0, err = 0;
      for (std::size_t d = 0; d < 3; ++d) {
        motion += std::pow(double{truth[v + d]} - rig->neutral[v + d], 2);
        err += std::pow(double{out[v + d]} - truth[v + d], 2);
      }
      all.push_back(std::sqrt(err));
      if (std::sqrt(motion) >= min_motion) moving.push_back(std::sqrt(err));
    }
  }
  Scored s;
  s.moving = stats_of(moving);
  s.all_mean = stats_of(all).mean;
  s.frames = take->info.frame_count;
  for (int col : *columns) s.driven += col >= 0 ? 1 : 0;
  s.shapes = rig->shape_count();
  s.curves = static_cast<int>(take->info.shape_names.size());
  return s;
}

nlohmann::json json_of(const Scored& s) {
  return {{"moving_mm",
           {{"mean", s.moving.mean},
            {"median", s.moving.median},
            {"p95", s.moving.p95},
            {"count", s.moving.count}}},
          {"all_vertices_mean_mm", s.all_mean},
          {"frames", s.frames},
          {"rig_shapes", s.shapes},
          {"shapes_driven", s.driven},
          {"take_curves", s.curves}};
}

// A performance tracked: sim/subject's synthetic take (random identity, smooth random tracks of
// 5 shapes, Kinect noise, true landmarks + 1.5 px noise) through the face model's tracker with
// the identity known. Returns the true and the tracked weights per frame.
Result<std::pair<std::vector<std::vector<float>>, std::vector<std::vector<float>>>> tracked(
    const FaceModel& model, int frames, std::uint64_t seed) {
  TakeSpec spec;
  spec.seed = seed;
  spec.frames = frames;
  auto take = render_take(model, spec);
  if (!take) return take.failure();
  auto tracker = FaceTracker::create(model, take->intrinsics);
  if (!tracker) return tracker.failure();
  if (auto ok = (*tracker)->set_identity(take->frames[0].truth.identity_coeffs); !ok)
    return ok.failure();
  const auto k = static_cast<std::size_t>(model.fitting_expression_count);
  std::vector<std::vector<float>> truth, weights;
  TrackReport report;
  for (std::size_t f = 0; f < take->frames.size(); ++f) {
    const TakeFrame& tf = take->frames[f];
    const TrackLandmarks landmarks{tf.landmarks, {}};
    (*tracker)->track(tf.depth, static_cast<double>(f) / 30.0, &landmarks, report);
    weights.emplace_back(report.weights.begin(), report.weights.begin() + static_cast<long>(k));
    truth.push_back(tf.truth.expression_weights);
    truth.back().resize(k, 0.0f);
  }
  return std::make_pair(std::move(truth), std::move(weights));
}

int run_eval_retarget(const ParsedOptions& options) {
  auto frames = options.get_int("frames");
  auto min_motion = options.get_double("min-motion");
  if (!frames || *frames < 1 || !min_motion || *min_motion < 0)
    return report_failure({"--frames N >= 1, --min-motion MM >= 0"});
  auto model = load_face_model();
  if (!model) return report_failure(model.error());
  const fs::path dir =
      fs::temp_directory_path() / ("facebooth-eval-retarget-" + std::to_string(::getpid()));
  nlohmann::json out;
  // 1. The path alone: the recipe's true weights stored as the take.
  fs::remove_all(dir);
  auto stored = make_retarget_case(dir / "stored", *model, static_cast<int>(*frames));
  if (!stored) return report_failure(stored.error());
  auto s1 = score(dir / "stored", *model, *stored, *min_motion);
  if (!s1) return report_failure(s1.error());
  // 2. The weights tracked from a rendered performance of the recipe.
  std::cerr << "eval retarget: tracking a synthetic take of " << *frames << " frames\n";
  auto weights = tracked(*model, static_cast<int>(*frames), 3);
  if (!weights) return report_failure(weights.error());
  auto live = make_retarget_case(dir / "tracked", *model, weights->first, weights->second);
  if (!live) return report_failure(live.error());
  auto s2 = score(dir / "tracked", *model, *live, *min_motion);
  if (!s2) return report_failure(s2.error());
  fs::remove_all(dir);
  out["retarget_vertex_error_mm"] = s2->moving.mean;
  out["retarget_stored_weights_error_mm"] = s1->moving.mean;
  out["retarget"] = {{"tracked", json_of(*s2)}, {"stored_weights", json_of(*s1)}};
  out["targets"] = {{"retarget_vertex_error_mm", 0.5}};
  out["definition"] =
      "A real session store with synthetic subjects A and B, each a personal rig "
      "(sim/subject/synthetic_rigs: face-model identity, every fitting shape at its own "
      "amplitude). A take is stored under A as the tracker stores takes (the 52 ARKit curves, "
      "TakeWriter) and each frame retargeted onto B's rig exactly as `facebooth retarget` does "
      "(curves matched to the rig's shapes by name); truth: B's rig at the recipe's model "
      "weights. retarget_vertex_error_mm (tracked): the recipe is sim/subject's synthetic take "
      "(seed 3: 5 shapes on smooth random tracks, Kinect noise, true landmarks + 1.5 px), its "
      "rendered frames tracked by the face model's tracker with the identity known, the tracked "
      "weights stored as the take. retarget_stored_weights_error_mm: sim/camera's expressive "
      "track (jaw, smile, blinks, brows) with its true weights stored as the take (the path "
      "alone). Mean distance over vertices the truth moves >= --min-motion mm from B's neutral, "
      "all frames.";
  std::cout << out.dump(2) << std::endl;
  return kExitOk;
}

}  // namespace

Command eval_retarget_command() {
  return {{"eval retarget",
           "score a stored take driving another subject's rig against the truth (JSON on stdout)",
           "See the JSON's definition field.",
           {{"frames", "N", "take length", "150"},
            {"min-motion", "MM", "vertices moving less are not scored", "0.1"},
            {"json", "", "JSON report on stdout (the only output format)", ""}}},
          run_eval_retarget};
}

}  // namespace fb::cli
