// facebooth-lab bench rig: rigging one synthetic subject and building the bootstrap bilinear
// model, timed (JSON on stdout).
#include <algorithm>
#include <chrono>
#include <iostream>
#include <nlohmann/json.hpp>

#include "algo/bilinear/bootstrap.hpp"
#include "algo/core/clock.hpp"
#include "algo/rigging/example_rigging.hpp"
#include "host/cli/guide_files.hpp"
#include "host/cli/rig_session.hpp"
#include "host/cli/rig_support.hpp"
#include "host/cli/stats.hpp"
#include "sim/lab/lab_commands.hpp"
#include "storage/asset_files.hpp"
#include "storage/durable_file.hpp"

namespace fb::cli {
namespace {

int run_bench_rig(const ParsedOptions& options) {
  auto seed = options.get_int("seed");
  auto repeats = options.get_int("repeats");
  auto identities = options.get_int("identities");
  if (!seed || !repeats || *repeats < 1 || !identities || *identities < 2)
    return report_failure({"--seed N, --repeats >= 1, --identities >= 2"});
  auto model = load_face_model();
  if (!model) return report_failure(model.error());
  auto guide = load_guide(*model, options.get("guide"));
  if (!guide) return report_failure(guide.error());
  RigOptions ro;
  ro.weight_vertices = model->fitting_vertices;
  const auto identity = identity_draw(static_cast<std::uint64_t>(*seed), model->identity_count);
  std::vector<std::vector<float>> generic, examples, weights;
  RigInput input = generic_rig_input(*model, generic);
  for (const auto& ge : guide->expressions) {
    auto w = guide_weights(ge, *model);
    if (!w) return report_failure(w.error());
    w->resize(static_cast<std::size_t>(model->fitting_expression_count));
    examples.push_back(face(*model, identity, *w));
    weights.push_back(*w);
  }
  for (const auto& e : examples) input.examples.emplace_back(e);
  input.example_weights = weights;
  Samples rig_s, build_s, serialize_s, parse_s;
  for (long long r = 0; r < *repeats; ++r) {
    std::cerr << "bench rig: repeat " << r + 1 << "/" << *repeats << "\n";
    const auto t0 = Clock::now();
    auto rig = rig_subject(input, ro);
    if (!rig) return report_failure(rig.error());
    rig_s.add(seconds_since(t0));
    auto built = build_from_face_model(*model, static_cast<int>(*identities), 1, 50, 25);
    if (!built) return report_failure(built.error());
    build_s.add(built->build_s);
    const auto t1 = Clock::now();
    const auto bytes = serialize_bilinear_model(built->model);
    serialize_s.add(seconds_since(t1));
    const auto t2 = Clock::now();
    auto parsed = parse_bilinear_model(bytes);
    if (!parsed) return report_failure(parsed.error());
    parse_s.add(seconds_since(t2));
  }
  nlohmann::json out;
  out["rig_s"] = rig_s.min();
  out["model_build_s"] = build_s.min();
  out["model_serialize_s"] = serialize_s.min();
  out["model_parse_s"] = parse_s.min();
  out["threads"] = ro.threads;
  out["definition"] =
      "best of --repeats, wall clock. rig_s: one subject, 20 examples, 53 blendshapes over "
      "11248 vertices, " +
      std::to_string(ro.rounds) + " rounds (" + std::to_string(ro.threads) +
      " threads for the per-triangle solves). model_build_s: bootstrap tensor from the face model "
      "(" +
      std::to_string(*identities) +
      " identities x 54 expressions, factored), N-mode SVD, "
      "truncation to 50 x 25 and the dense core; serialisation and parsing are separate figures, "
      "writing the file is not timed";
  out["targets"] = {{"rig_s", 10}, {"model_build_s", 60}};
  std::cout << out.dump(2) << std::endl;
  return kExitOk;
}

}  // namespace

Command bench_rig_command() {
  const OptionSpec guide_opt{"guide", "FILE",
                             "guide recipes (default: DATA_DIR/guide_expressions.json)", ""};
  const OptionSpec json_opt{"json", "", "JSON report on stdout (the only output format)", ""};
  return {{"bench rig",
           "time rigging one subject and building the bootstrap model (JSON on stdout)",
           "",
           {{"seed", "N", "synthetic subject", "1"},
            {"repeats", "N", "best of N", "3"},
            {"identities", "N", "identities of the timed model build", "150"},
            guide_opt,
            json_opt}},
          run_bench_rig};
}

}  // namespace fb::cli
