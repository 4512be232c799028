// facebooth-lab eval retarget: a stored take of synthetic subject A driving subject B's rig, as
// `facebooth retarget` does it (host/cli/retarget.hpp), against B's own truth for the same
// recipe (sim/subject/retarget_case.hpp), in a real SQLite session store.
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <iostream>

#include <nlohmann/json.hpp>

#include "host/cli/retarget.hpp"
#include "host/cli/stats.hpp"
#include "sim/lab/transfer_image_lab.hpp"
#include "sim/subject/retarget_case.hpp"
#include "storage/asset_files.hpp"

namespace fb::cli {

namespace {

namespace fs = std::filesystem;

int run_eval_retarget(const ParsedOptions& options) {
  auto frames = options.get_int("frames");
  auto min_motion = options.get_double("min-motion");
  if (!frames || *frames < 1 || !min_motion || *min_motion < 0)
    return report_failure({"--frames N >= 1, --min-motion MM >= 0"});
  auto model = load_face_model();
  if (!model) return report_failure(model.error());
  const fs::path dir =
      fs::temp_directory_path() / ("facebooth-eval-retarget-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  auto c = make_retarget_case(dir, *model, static_cast<int>(*frames));
  if (!c) return report_failure(c.error());
  StoreOptions so;
  so.read_only = true;
  so.create = false;
  auto store = SessionStore::open(dir, so);
  if (!store) return report_failure(store.error());
  auto take = store->read_take(c->take);
  if (!take) return report_failure(take.error());
  auto target = rig_for_target(*store, "subject:" + std::to_string(c->target));
  if (!target) return report_failure(target.error());
  auto rig = store->read_rig(target->id);
  if (!rig) return report_failure(rig.error());
  auto columns = take_columns_for_rig(take->info.shape_names, rig->shape_names);
  if (!columns) return report_failure(columns.error());
  std::vector<double> moving, all;
  for (int f = 0; f < take->info.frame_count; ++f) {
    const auto out = retarget_frame(*take, f, *rig, *columns);
    const auto truth = retarget_truth(*c, *model, f);
    for (std::size_t v = 0; v + 2 < truth.size(); v += 3) {
      double motion = 0, err = 0;
      for (std::size_t d = 0; d < 3; ++d) {
        motion += std::pow(double{truth[v + d]} - rig->neutral[v + d], 2);
        err += std::pow(double{out[v + d]} - truth[v + d], 2);
      }
      all.push_back(std::sqrt(err));
      if (std::sqrt(motion) >= *min_motion) moving.push_back(std::sqrt(err));
    }
  }
  fs::remove_all(dir);
  int driven = 0;
  for (int col : *columns) driven += col >= 0 ? 1 : 0;
  const Summary s = stats_of(moving);
  nlohmann::json out;
  out["retarget_vertex_error_mm"] = s.mean;
  out["retarget"] = {
      {"moving_mm", {{"mean", s.mean}, {"median", s.median}, {"p95", s.p95}, {"count", s.count}}},
      {"all_vertices_mean_mm", stats_of(all).mean},
      {"frames", take->info.frame_count},
      {"rig_shapes", rig->shape_count()},
      {"shapes_driven", driven},
      {"take_curves", take->info.shape_names.size()}};
  out["targets"] = {{"retarget_vertex_error_mm", 0.5}};
  out["definition"] =
      "A real session store with synthetic subjects A and B, each a personal rig "
      "(sim/subject/synthetic_rigs: face-model identity, every fitting shape at its own "
      "amplitude). A's take: sim/camera's expressive track (jaw, smile, blinks, brows) as model "
      "weights, stored as the tracker stores takes (the 52 ARKit curves, TakeWriter) -- the "
      "recipe's true weights, not weights tracked from rendered frames. Each frame retargeted "
      "onto B's rig exactly as `facebooth retarget` does (curves matched to the rig's shapes by "
      "name); truth: B's rig at the recipe's model weights. retarget_vertex_error_mm: mean "
      "distance over vertices the truth moves >= --min-motion mm from B's neutral, all frames.";
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
