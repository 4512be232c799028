// facebooth-lab eval fit | bench fit: the landmark and face-fitting stage
// (FaceWarehouse 3.2.1-3.2.2, algo/landmarks + algo/fitting + algo/guide) scored on synthetic
// subjects with ground truth. One JSON object on stdout, progress on stderr. This file: the
// commands' option tables and eval fit over its scenarios; the parts are in fit_eval_parts.hpp.
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>

#include "host/cli/guide_files.hpp"
#include "sim/camera/world_presets.hpp"
#include "sim/lab/fit_eval_parts.hpp"
#include "sim/lab/lab_commands.hpp"
#include "storage/asset_files.hpp"

namespace fb::cli::fit_eval {

// The shape predictor: the plain .dat, or a .dat.bz2 decompressed once into a cache directory.
Result<LandmarkDetector> load_detector(const std::string& option) {
  std::filesystem::path path = option.empty() ? kShapePredictorDefault : option;
  if (!std::filesystem::exists(path) && std::filesystem::exists(path.string() + ".bz2"))
    path += ".bz2";
  if (path.extension() == ".bz2") {
    const char* xdg = std::getenv("XDG_CACHE_HOME");
    const char* home = std::getenv("HOME");
    const std::filesystem::path cache =
        xdg ? std::filesystem::path(xdg) / "facebooth"
            : std::filesystem::path(home ? home : "/tmp") / ".cache" / "facebooth";
    const std::filesystem::path out = cache / path.stem();
    if (!std::filesystem::exists(out)) {
      std::error_code ec;
      std::filesystem::create_directories(cache, ec);
      std::cerr << "landmarks: decompressing " << path << " into " << out << " (once)...\n";
      const std::string tmp = out.string() + ".part";
      const std::string cmd = "bzip2 -dc '" + path.string() + "' > '" + tmp + "'";
      if (std::system(cmd.c_str()) != 0) return fail("could not decompress " + path.string());
      std::filesystem::rename(tmp, out, ec);
      if (ec) return fail("could not write " + out.string());
    }
    path = out;
  }
  std::ifstream in(path, std::ios::binary);
  if (!in)
    return fail("cannot read the landmark model " + path.string() +
                " (install Debian's libdlib-data or pass --shape-predictor)");
  return LandmarkDetector::create(in);
}

namespace {

Result<std::vector<int>> parse_expression_list(const std::string& text, const GuideSet& guide) {
  std::vector<int> out;
  if (text.empty() || text == "all") {
    for (std::size_t i = 0; i < guide.expressions.size(); ++i) out.push_back(static_cast<int>(i));
    return out;
  }
  std::stringstream s(text);
  std::string item;
  out.push_back(0);
  while (std::getline(s, item, ',')) {
    int id = guide.find(item);
    if (id < 0) {
      try {
        id = std::stoi(item);
      } catch (...) {
        id = -1;
      }
    }
    if (id < 0 || id >= static_cast<int>(guide.expressions.size()))
      return fail("--expressions: unknown expression '" + item + "' (names or ids 0-19, or all)");
    if (id != 0) out.push_back(id);
  }
  return out;
}

// A part that decalibrates the unit, run self-calibrated: the same run with the depth law known
// (registration self-calibrated), and on the unit calibrated perfectly (the reference
// self-calibration is held to), and the ratios to it.
Result<void> add_unit_calibration_runs(const ParsedOptions& options, const FitEvalSetup& setup,
                                       const std::string& part, nlohmann::json& run) {
  nlohmann::json ratio;
  for (const auto mode : {UnitCalibration::kSelfWithDepthLaw, UnitCalibration::kCalibrated}) {
    std::cerr << "eval fit: scenario " << part << ", unit " << unit_calibration_name(mode) << "\n";
    FitEvalSetup other = setup;
    other.unit_calibration = mode;
    auto c = eval_fit_once(options, other, part);
    if (!c) return c.failure();
    c->erase("per_subject");
    run[std::string("unit_") + unit_calibration_name(mode)] = std::move(*c);
  }
  const auto& reference = run["unit_calibrated"];
  for (const auto& [name, figures] : {std::pair<std::string, const nlohmann::json*>{"self", &run},
                                      {"self-depth-law", &run["unit_self-depth-law"]}})
    ratio[name] = {
        {"neutral_vertex_error_mm",
         ratio_of((*figures)["neutral_vertex_error_mm"], reference["neutral_vertex_error_mm"])},
        {"expression_vertex_error_mm", ratio_of((*figures)["expression_vertex_error_mm"],
                                                reference["expression_vertex_error_mm"])}};
  run["decalibrated_vs_calibrated_ratio"] = ratio;
  return success();
}

// Each part alone (and, for realistic, the plain world with the same landmarks as a
// baseline), then the scenario itself: its figures are the top level.
Result<nlohmann::json> run_fit_scenarios(const ParsedOptions& options, const FitEvalSetup& setup,
                                         const std::string& scenario,
                                         const std::vector<std::string>& parts) {
  nlohmann::json scenarios;
  nlohmann::json out;
  for (const auto& part : parts) {
    std::cerr << "eval fit: scenario " << part << "\n";
    auto run = eval_fit_once(options, setup, part == "baseline" ? "none" : part);
    if (!run) return run.failure();
    if (decalibrates_unit(part) && setup.unit_calibration == UnitCalibration::kSelfCalibrated)
      if (auto ok = add_unit_calibration_runs(options, setup, part, *run); !ok) return ok.failure();
    if (part == scenario) out = *run;
    run->erase("per_subject");
    scenarios[part] = std::move(*run);
  }
  out["scenario"] = scenario;
  out["scenarios"] = scenarios;
  out["unit_calibration"] = unit_calibration_name(setup.unit_calibration);
  return out;
}

Result<ExpressionStart> parse_expression_start(const std::string& name) {
  if (name == "model") return ExpressionStart::kModelShapes;
  if (name == "transfer") return ExpressionStart::kDeformationTransfer;
  return fail("eval fit: --expression-start must be model or transfer, not '" + name + "'");
}

int run_eval_fit(const ParsedOptions& options) {
  auto identities = options.get_int("identities");
  if (!identities) return report_failure(identities.error());
  auto first_seed = options.get_int("first-seed");
  if (!first_seed) return report_failure(first_seed.error());
  auto frames = options.get_int("frames");
  if (!frames) return report_failure(frames.error());
  auto noise = options.get_double("landmark-noise-px");
  if (!noise) return report_failure(noise.error());
  auto robust_noise = options.get_double("robustness-noise-px");
  if (!robust_noise) return report_failure(robust_noise.error());
  if (*identities < 1 || *frames < 2 || *noise < 0)
    return report_failure({"--identities >= 1, --frames >= 2 and --landmark-noise-px >= 0"});
  for (const char* name : {"skin-map", "scale-parts", "offsets"})
    if (const std::string v = options.get(name); v != "on" && v != "off")
      return report_failure({std::string("--") + name + " takes on or off, not '" + v + "'"});
  auto start = parse_expression_start(options.get("expression-start"));
  if (!start) return report_failure(start.error());
  auto model = load_face_model();
  if (!model) return report_failure(model.error());
  auto guide = load_guide(*model, options.get("guide"));
  if (!guide) return report_failure(guide.error());
  auto model_system = model_refine_system(*model);
  if (!model_system) return report_failure(model_system.error());
  const bool noiseless_depth = options.get("depth") == "noiseless";  // diagnostics only
  auto expressions = parse_expression_list(options.get("expressions"), *guide);
  if (!expressions) return report_failure(expressions.error());
  const std::string scenario = options.get("scenario");
  const std::string fit_landmarks = options.get("fit-landmarks").empty()
                                        ? (scenario.empty() ? "truth" : "dlib")
                                        : options.get("fit-landmarks");
  if (fit_landmarks != "truth" && fit_landmarks != "dlib")
    return report_failure({"--fit-landmarks must be truth or dlib"});
  if (fit_landmarks == "dlib" && options.get("dlib") == "off")
    return report_failure({"--fit-landmarks dlib needs dlib: drop --dlib off"});
  std::vector<std::string> parts;
  if (!scenario.empty()) {
    SyntheticOptions probe;
    if (auto ok = apply_world_preset(scenario, 1, probe); !ok) return report_failure(ok.error());
    if (scenario == "realistic") {
      parts = {"baseline"};
      for (const auto& p : world_parts()) parts.push_back(p);
    }
    parts.push_back(scenario);
  }
  std::optional<LandmarkDetector> detector;
  if (options.get("dlib") != "off") {
    std::cerr << "eval fit: loading the dlib landmark model...\n";
    auto d = load_detector(options.get("shape-predictor"));
    if (!d) return report_failure(d.error());
    detector.emplace(std::move(*d));
  }
  FitEvalSetup setup;
  setup.model = &*model;
  setup.guide = &*guide;
  setup.model_system = &*model_system;
  setup.detector = detector ? &*detector : nullptr;
  setup.expressions = *expressions;
  setup.identities = *identities;
  setup.first_seed = *first_seed;
  setup.frames = *frames;
  setup.noise = *noise;
  setup.robust_noise = *robust_noise;
  setup.noiseless_depth = noiseless_depth;
  setup.skin_map = options.get("skin-map") != "off";
  setup.scale_parts = options.get("scale-parts") != "off";
  setup.offsets = options.get("offsets") != "off";
  setup.expression_start = *start;
  setup.dlib_fit = fit_landmarks == "dlib";
  if (const std::string e = options.get("landmark-embedding"); e != "model") {
    auto embedding = e == "dlib" ? load_landmark_embedding(*model)
                                 : load_landmark_embedding(*model, std::filesystem::path(e));
    if (!embedding) return report_failure(embedding.error());
    setup.embedding = *embedding;
  }
  auto unit_calibration = parse_unit_calibration(options.get("unit-calibration"));
  if (!unit_calibration) return report_failure(unit_calibration.error());
  setup.unit_calibration = *unit_calibration;
  if (parts.empty()) {
    auto out = eval_fit_once(options, setup, "");
    if (!out) return report_failure(out.error());
    std::cout << out->dump(2) << std::endl;
    return kExitOk;
  }
  auto out = run_fit_scenarios(options, setup, scenario, parts);
  if (!out) return report_failure(out.error());
  std::cout << out->dump(2) << std::endl;
  return kExitOk;
}

}  // namespace
}  // namespace fb::cli::fit_eval

namespace fb::cli {

std::vector<Command> fit_commands() {
  using fit_eval::kShapePredictorDefault;
  const OptionSpec guide_opt{"guide", "FILE",
                             "guide recipes (default: DATA_DIR/guide_expressions.json)", ""};
  const OptionSpec predictor_opt{"shape-predictor", "FILE",
                                 "dlib 68-point model (.dat or .dat.bz2)", kShapePredictorDefault};
  const OptionSpec json_opt{"json", "",
                            "print JSON (the only output format; accepted for symmetry)", ""};
  return {
      {{"eval fit",
        "score landmarks + neutral/expression fitting on synthetic subjects (JSON on stdout)",
        "Each capture: synthetic head-turn take with sensor noise -> KinectFusion -> fused frontal "
        "depth; landmarks are the true colour-image points plus Gaussian noise (dlib is scored "
        "separately on the same renders). The full figure run is --identities 5 (all 20 "
        "expressions).",
        {{"identities", "N", "synthetic subjects (random identity each)", "5"},
         {"first-seed", "N", "seed of the first subject", "1"},
         {"expressions", "LIST", "all, or comma-separated names/ids (neutral always runs)", "all"},
         {"frames", "N", "frames per head-turn take fused", "45"},
         landmark_noise_option(),
         {"robustness-noise-px", "PX", "extra neutral fit with this landmark noise (0 = skip)",
          "5"},
         {"png", "FILE", "error map of the first neutral fit (initial | refined)", ""},
         {"dlib", "on|off", "score dlib's landmarks on the renders", "on"},
         {"scenario", "NAME",
          "realistic (every part alone, a baseline, then all together; JSON scenarios.<part>) or "
          "one part: identity|texture|hair|clutter|noise|unit (sim/camera/"
          "world_presets.hpp); empty = the plain synthetic camera",
          ""},
         {"unit-calibration", "self|self-depth-law|reported|calibrated", kUnitCalibrationHelp,
          "self"},
         {"fit-landmarks", "dlib|truth",
          "the fit's landmarks: dlib on frame 0's colour image, or truth + --landmark-noise-px "
          "(default: dlib with --scenario, truth without)",
          ""},
         {"depth", "fused|noiseless",
          "fit the fused depth (the figure) or, to isolate fusion "
          "error, the noiseless rendering",
          "fused"},
         {"skin-map", "on|off",
          "weigh the depth by where frame 0's colour sees skin (hair and beard as bounds, "
          "contour points on them dropped), as the product does; off for an A/B",
          "on"},
         {"offsets", "on|off",
          "let the neutral fit's PCA step bend the surface along its normal where the identity "
          "modes cannot hold this face (NeutralFitOptions::offset_amplitude_mm), as the product "
          "does; off for an A/B",
          "on"},
         {"scale-parts", "on|off",
          "scale each part of an expression's guide recipe to the capture before refining (how far "
          "this person opened the jaw), as the product does; off for an A/B",
          "on"},
         {"expression-start", "model|transfer",
          "where an expression fit starts: the face model's own expression shapes added to the "
          "fitted neutral, as the product does, or the guide's deformation transferred onto it "
          "(FaceWarehouse 3.2.2); transfer for an A/B",
          "model"},
         {"landmark-embedding", "dlib|model|FILE",
          "the mesh vertices dlib's points mark in the fit: dlib = DATA_DIR/"
          "dlib_landmark_embedding.csv (as the product), model = the model's own landmark "
          "vertices, or a file from `landmarks embed`",
          "dlib"},
         predictor_opt,
         guide_opt,
         json_opt}},
       fit_eval::run_eval_fit},
      {{"bench fit",
        "time landmarks, neutral fit and expression fits (JSON on stdout)",
        "",
        {{"seed", "N", "synthetic subject", "1"},
         {"repeats", "N", "best of N", "3"},
         {"dlib", "on|off", "time the dlib landmark tracker", "on"},
         predictor_opt,
         guide_opt,
         json_opt}},
       fit_eval::run_bench_fit},
  };
}

}  // namespace fb::cli