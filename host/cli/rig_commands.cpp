// facebooth rig | model build: example-based rigging
// (algo/rigging, FaceWarehouse 3.2.3) and the bilinear model (algo/bilinear, 3.3 and 4.1-4.4).
// JSON on stdout, progress on stderr.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <numeric>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <sstream>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include "algo/bilinear/bootstrap.hpp"
#include "algo/bilinear/image_fit.hpp"
#include "algo/core/clock.hpp"
#include "algo/fitting/expression_transfer.hpp"
#include "algo/rigging/example_rigging.hpp"
#include "host/cli/commands.hpp"
#include "host/cli/guide_files.hpp"
#include "host/cli/progress.hpp"
#include "host/cli/rig_session.hpp"
#include "host/cli/rig_support.hpp"
#include "host/cli/session_model_build.hpp"
#include "host/cli/session_refit.hpp"
#include "host/cli/stats.hpp"
#include "storage/asset_files.hpp"
#include "storage/durable_file.hpp"
#include "storage/export/facewarehouse.hpp"
#include "storage/session_store.hpp"

namespace fb::cli {

// Mean distance over `subset` between mesh a (mapped by `a_to_b`) and mesh b.
double mean_distance(std::span<const float> a, std::span<const float> b,
                     std::span<const std::uint32_t> subset, const RigidPose& a_to_b) {
  double s = 0;
  for (auto v : subset) {
    const Eigen::Vector3d p = a_to_b.apply({a[3 * v], a[3 * v + 1], a[3 * v + 2]});
    s += (p - Eigen::Vector3d(b[3 * v], b[3 * v + 1], b[3 * v + 2])).norm();
  }
  return subset.empty() ? NAN : s / static_cast<double>(subset.size());
}

// Mean |R (a - a0) - (b - b0)| over `subset`: the expression part of two faces alone, without
// the error their neutrals share (R: a's model frame -> b's, rotation only).
double mean_delta_distance(std::span<const float> a, std::span<const float> a0,
                           std::span<const float> b, std::span<const float> b0,
                           std::span<const std::uint32_t> subset, const Eigen::Quaterniond& r) {
  double s = 0;
  for (auto v : subset) {
    const Eigen::Vector3d da(a[3 * v] - a0[3 * v], a[3 * v + 1] - a0[3 * v + 1],
                             a[3 * v + 2] - a0[3 * v + 2]);
    const Eigen::Vector3d db(b[3 * v] - b0[3 * v], b[3 * v + 1] - b0[3 * v + 1],
                             b[3 * v + 2] - b0[3 * v + 2]);
    s += (r * da - db).norm();
  }
  return subset.empty() ? NAN : s / static_cast<double>(subset.size());
}

std::vector<float> face(const FaceModel& model, std::span<const float> identity,
                        std::span<const float> weights) {
  std::vector<float> m(static_cast<std::size_t>(model.vertex_count) * 3);
  model.evaluate(identity, weights, m);
  return m;
}

// A rig progress bar over the whole job (0..1000).
std::function<void(std::string_view, double)> rig_progress(std::shared_ptr<Progress> bar) {
  return [bar](std::string_view, double f) { bar->update(static_cast<long long>(f * 1000)); };
}

Result<RigOptions> rig_options(const ParsedOptions& options, const FaceModel& model) {
  RigOptions o;
  auto rounds = options.get_int("rounds");
  if (!rounds) return rounds.failure();
  auto prior = options.get_double("prior-weight");
  if (!prior) return prior.failure();
  auto reg = options.get_double("weight-regularization");
  if (!reg) return reg.failure();
  if (*rounds < 1 || *rounds > 20) return fail("--rounds must be 1..20");
  if (!(*prior > 0)) return fail("--prior-weight must be positive");
  if (!(*reg >= 0)) return fail("--weight-regularization must be >= 0");
  o.rounds = static_cast<int>(*rounds);
  o.prior_weight = *prior;
  o.weight_regularization = *reg;
  o.weight_vertices = model.fitting_vertices;
  return o;
}

std::vector<OptionSpec> rig_option_specs() {
  const RigOptions d;
  return {{"rounds", "N", "alternations of blendshape solve and example-weight update",
           std::to_string(d.rounds)},
          {"prior-weight", "BETA", "weight of the generic-rig prior (Li et al.'s beta)", "0.2"},
          {"weight-regularization", "GAMMA",
           "pull of the re-estimated example weights towards the guide recipes (mm^2)", "0.05"}};
}

Result<RigInputs> load_rig_inputs(const ParsedOptions& options) {
  auto model = load_face_model();
  if (!model) return model.failure();
  auto guide = load_guide(*model, options.get("guide"));
  if (!guide) return guide.failure();
  auto rig = rig_options(options, *model);
  if (!rig) return rig.failure();
  return RigInputs{std::move(*model), std::move(*guide), std::move(*rig)};
}

// Random held-out expression mixes: every fitting shape is on with probability 0.2, U(0, 1).
std::vector<std::vector<float>> random_mixes(int count, int shapes, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::vector<std::vector<float>> out;
  for (int k = 0; k < count; ++k) {
    std::vector<float> w(static_cast<std::size_t>(shapes), 0.0f);
    for (auto& x : w)
      if (u(rng) < 0.2f) x = u(rng);
    out.push_back(std::move(w));
  }
  return out;
}

Result<BuiltModel> build_from_face_model(const FaceModel& face_model, int identities,
                                         std::uint64_t seed, int id_knobs, int exp_knobs) {
  const auto t0 = Clock::now();
  const auto ids = draw_identities(face_model, identities, seed);
  const FactoredTensor tensor = bootstrap_tensor(face_model, ids);
  auto factors = mode_factors(tensor);
  if (!factors) return factors.failure();
  auto truncated = truncate(tensor, *factors, id_knobs, exp_knobs);
  if (!truncated) return fail("model build: " + truncated.error().message);
  BuiltModel b;
  b.info = {{"source", "face model bootstrap"},
            {"identities", identities},
            {"seed", seed},
            {"expressions", tensor.expressions},
            {"id_knobs", id_knobs},
            {"exp_knobs", exp_knobs},
            {"tensor",
             "factored: basis [neutral, identity modes, expression deltas] x "
             "coefficients (the dense tensor is never formed)"}};
  b.model = make_bilinear_model(*truncated, face_model, bootstrap_expression_names(face_model),
                                b.info.dump());
  b.build_s = seconds_since(t0);
  return b;
}

namespace {

nlohmann::json residual_json(const RigResult& rig, const std::vector<std::string>& names,
                             const FaceModel& model,
                             const std::vector<std::vector<float>>& guide_weights) {
  nlohmann::json per = nlohmann::json::array();
  for (std::size_t i = 0; i < rig.vertex_residual_mm.size(); ++i) {
    double s = 0, worst = 0;
    for (auto v : model.fitting_vertices) {
      const double r = rig.vertex_residual_mm[i][v];
      s += r;
      worst = std::max(worst, r);
    }
    double dw = 0;
    for (std::size_t j = 0; j < rig.weights[i].size(); ++j)
      dw = std::max(dw, std::abs(static_cast<double>(rig.weights[i][j]) - guide_weights[i][j]));
    per.push_back({{"expression", names[i]},
                   {"mean_residual_mm", s / model.fitting_vertices.size()},
                   {"max_residual_mm", worst},
                   {"max_weight_change", dw}});
  }
  return per;
}

// ---------------------------------------------------------------------------------------------
// facebooth rig

// --refit: the session's captures fitted again with the host's settings, stored, summarised.
Result<nlohmann::json> run_refit(SessionStore& store, SessionId session, const FaceModel& model,
                                 const GuideSet& guide, bool dlib_landmarks) {
  RefitOptions ro = full_fit_options();
  if (dlib_landmarks) {
    auto embedding = landmark_embedding_beside(model, default_face_model_path());
    if (!embedding) return embedding.failure();
    ro.embedding = *embedding;
  }
  std::optional<Progress> bar;
  ro.progress = [&bar](int done, int total) {
    if (!bar) bar.emplace("refit: captures", total);
    bar->update(done);
  };
  std::cerr << "refit: session " << session << ", full fit (PCA + Laplacian refinement)\n";
  auto report = refit_session(store, session, model, guide, ro);
  bar.reset();
  if (!report) return report.failure();
  nlohmann::json per = nlohmann::json::array();
  for (const auto& c : report->captures)
    per.push_back({{"capture", c.index},
                   {"expression", c.expression},
                   {"mesh_id", c.mesh},
                   {"supersedes_mesh_id", c.previous_mesh},
                   {"rms_to_depth_mm", c.rms_to_depth_mm},
                   {"landmark_error_mm", c.landmark_error_mm},
                   {"fit_ms", c.fit_ms}});
  nlohmann::json j = {
      {"captures", per}, {"skipped", report->skipped}, {"refit_s", report->seconds}};
  if (!report->calibration_note.empty()) j["calibration_note"] = report->calibration_note;
  return j;
}

int run_rig(const ParsedOptions& options) {
  auto inputs = load_rig_inputs(options);
  if (!inputs) return report_failure(inputs.error());
  const FaceModel& model = inputs->model;
  const GuideSet& guide = inputs->guide;
  RigOptions& rig_opts = inputs->rig;
  const bool save = options.flag("save");
  const std::string store_dir = options.get("store");
  const std::string synthetic = options.get("synthetic");
  if (store_dir.empty() == synthetic.empty())
    return report_failure(
        {"give either --store DIR --session ID (a stored, fitted session) or --synthetic SEED "
         "(a synthetic subject's exact guide meshes)"});
  if (save && store_dir.empty()) return report_failure({"--save needs --store"});
  const bool refit = options.flag("refit");
  if (refit && store_dir.empty()) return report_failure({"--refit needs --store and --session"});
  const std::string convention = options.get("landmarks");
  if (convention != "dlib" && convention != "model")
    return report_failure({"--landmarks is dlib or model (got '" + convention + "')"});

  SessionExamples ex;
  nlohmann::json refit_json;
  std::optional<SessionStore> store;
  SessionId session = 0;
  if (!store_dir.empty()) {
    auto sid = options.get_int("session");
    if (!sid || *sid <= 0) return report_failure({"--session ID is required with --store"});
    session = *sid;
    StoreOptions so;
    so.read_only = !save && !refit;
    so.create = false;
    auto opened = SessionStore::open(store_dir, so);
    if (!opened) return report_failure(opened.error());
    store.emplace(std::move(*opened));
    if (refit) {
      auto done = run_refit(*store, session, model, guide, convention == "dlib");
      if (!done) return report_failure(done.error());
      refit_json = std::move(*done);
    }
    auto loaded =
        load_session_examples(*store, session, model, guide, options.flag("allow-missing"));
    if (!loaded) return report_failure(loaded.error());
    ex = std::move(*loaded);
  } else {
    auto seed = options.get_int("synthetic");
    if (!seed) return report_failure(seed.error());
    const auto identity = identity_draw(static_cast<std::uint64_t>(*seed), model.identity_count);
    for (const auto& ge : guide.expressions) {
      auto w = guide_weights(ge, model);
      if (!w) return report_failure(w.error());
      w->resize(static_cast<std::size_t>(model.fitting_expression_count));
      ex.meshes.push_back(face(model, identity, *w));
      ex.weights.push_back(*w);
      ex.names.push_back(ge.name);
      ex.capture_indices.push_back(ge.id);
    }
  }
  auto bar = std::make_shared<Progress>("rig", 1000);
  rig_opts.progress = rig_progress(bar);
  auto rigged = rig_examples(ex, model, rig_opts);
  bar.reset();
  if (!rigged) return report_failure(rigged.error());
  const RigResult* rig = &rigged->result;
  const RigData& data = rigged->data;

  nlohmann::json out;
  if (refit) out["refit"] = refit_json;
  out["examples"] = ex.names.size();
  out["missing"] = ex.missing;
  out["blendshapes"] = data.shape_count();
  out["vertices"] = data.vertex_count();
  out["rig_s"] = rig->seconds;
  out["round_mean_residual_mm"] = rig->round_residual_mm;
  out["residual_region"] = "mean over the model's fitting vertices";
  out["per_example"] = residual_json(*rig, ex.names, model, ex.weights);
  const std::filesystem::path dir = options.get("out");
  if (!dir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(dir, ec);
    if (ec) return report_failure({"cannot create " + dir.string() + ": " + ec.message()});
    const auto bs = encode_shape_bs(data);
    if (auto w = write_file_durably(dir / "shape.bs", bs); !w) return report_failure(w.error());
    // Per-example, per-vertex residuals: (examples x V) little-endian f32.
    std::vector<std::uint8_t> raw;
    for (const auto& r : rig->vertex_residual_mm) {
      const auto* p = reinterpret_cast<const std::uint8_t*>(r.data());
      raw.insert(raw.end(), p, p + r.size() * sizeof(float));
    }
    if (auto w = write_file_durably(dir / "residuals.f32", raw); !w)
      return report_failure(w.error());
    nlohmann::json meta = out;
    meta["weights"] = rig->weights;
    meta["residuals_f32"] =
        "residuals.f32: examples x vertices float32, mm, example order as "
        "per_example";
    const std::string text = meta.dump(2);
    if (auto w = write_file_durably(
            dir / "rig.json",
            std::span(reinterpret_cast<const std::uint8_t*>(text.data()), text.size()));
        !w)
      return report_failure(w.error());
    out["out"] = std::filesystem::absolute(dir).string();
  }
  if (save) {
    auto id = store->add_rig(ex.subject, session, data);
    if (!id) return report_failure(id.error());
    out["rig_id"] = *id;
  }
  std::cout << out.dump(2) << std::endl;
  return kExitOk;
}

// ---------------------------------------------------------------------------------------------
// facebooth model build

double energy_kept(const std::vector<float>& spectrum, int knobs) {
  double all = 0, kept = 0;
  for (std::size_t i = 0; i < spectrum.size(); ++i) {
    all += spectrum[i];
    if (static_cast<int>(i) < knobs) kept += spectrum[i];
  }
  return all > 0 ? kept / all : NAN;
}

Result<void> write_model(const BilinearModel& model, const std::filesystem::path& path,
                         nlohmann::json& out) {
  const auto t0 = Clock::now();
  const auto bytes = serialize_bilinear_model(model);
  out["serialize_s"] = seconds_since(t0);
  const auto t1 = Clock::now();
  if (auto w = write_file_durably(
          path, std::span(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size()));
      !w)
    return w.failure();
  out["write_s"] = seconds_since(t1);
  out["bytes"] = bytes.size();
  out["out"] = std::filesystem::absolute(path).string();
  return success();
}

int run_model_build(const ParsedOptions& options) {
  const std::filesystem::path out_path = options.get("out");
  if (out_path.empty()) return report_failure({"--out FILE is required"});
  const bool from_model = options.flag("from-face-model");
  const bool from_sessions = options.flag("from-sessions");
  if (from_model == from_sessions)
    return report_failure({"give exactly one of --from-face-model and --from-sessions"});
  auto id_knobs = options.get_int("id-knobs");
  auto exp_knobs = options.get_int("exp-knobs");
  auto identities = options.get_int("identities");
  auto seed = options.get_int("seed");
  if (!id_knobs || !exp_knobs || !identities || !seed)
    return report_failure({"--id-knobs, --exp-knobs, --identities and --seed take integers"});
  auto face_model = load_face_model();
  if (!face_model) return report_failure(face_model.error());
  std::cerr << "model build: " << (from_model ? "bootstrap from the face model" : "from sessions")
            << "...\n";
  SessionModelOptions so;
  so.store = options.get("store");
  so.sessions = options.get("sessions");
  so.id_knobs = static_cast<int>(*id_knobs);
  so.exp_knobs = static_cast<int>(*exp_knobs);
  so.in_memory = options.flag("in-memory");
  auto memory_mb = options.get_int("memory-mb");
  if (!memory_mb || *memory_mb < 16) return report_failure({"--memory-mb takes an integer >= 16"});
  so.memory_mb = static_cast<std::size_t>(*memory_mb);
  Result<BuiltModel> built =
      from_model ? build_from_face_model(*face_model, static_cast<int>(*identities),
                                         static_cast<std::uint64_t>(*seed),
                                         static_cast<int>(*id_knobs), static_cast<int>(*exp_knobs))
                 : build_from_sessions(*face_model, so);
  if (!built) return report_failure(built.error());
  nlohmann::json out = built->info;
  out["model_build_s"] = built->build_s;
  out["identity_energy_kept"] = energy_kept(built->model.identity_spectrum, built->model.id_knobs);
  out["expression_energy_kept"] =
      energy_kept(built->model.expression_spectrum, built->model.exp_knobs);
  std::cerr << "model build: writing " << out_path << "...\n";
  if (auto w = write_model(built->model, out_path, out); !w) return report_failure(w.error());
  std::cout << out.dump(2) << std::endl;
  return kExitOk;
}

}  // namespace

std::vector<Command> rig_commands() {
  const OptionSpec guide_opt{"guide", "FILE",
                             "guide recipes (default: DATA_DIR/guide_expressions.json)", ""};
  std::vector<OptionSpec> rig_opts = {
      {"store", "DIR", "session store holding the fitted session", ""},
      {"session", "ID", "the session to rig (its fitted neutral + expression meshes)", ""},
      {"synthetic", "SEED",
       "instead of a store: rig synthetic subject SEED from its exact guide meshes", ""},
      {"allow-missing", "",
       "rig from the fitted expressions that are there (default: refuse a session with missing "
       "fitted meshes and list them)",
       ""},
      {"out", "DIR",
       "write shape.bs (FaceWarehouse blendshape file), rig.json (residuals, re-estimated "
       "weights) and residuals.f32 (examples x vertices, mm)",
       ""},
      {"save", "", "store the rig in --store (subject of the session)", ""},
      {"refit", "",
       "first fit every capture again from its stored fused depth and landmarks with the "
       "host's full settings (the booth's fits are kept but superseded), then rig from those",
       ""},
      {"landmarks", "dlib|model",
       "with --refit: the convention of the stored landmarks: dlib (the booth stores dlib's "
       "points; their vertices from dlib_landmark_embedding.csv beside the face model) or model "
       "(points that mark the face model's own landmark vertices, e.g. synthetic truth)",
       "dlib"},
      guide_opt};
  for (const auto& o : rig_option_specs()) rig_opts.push_back(o);
  return {
      {{"rig", "example-based rigging: personal blendshapes from a session's fitted expressions",
        "Li, Weise and Pauly 2010 (FaceWarehouse 3.2.3): the 53 fitting blendshapes of the face "
        "model are personalised in deformation-gradient space from the fitted guide expressions "
        "and their known weights (the guide recipes), alternating with a bounded re-estimation "
        "of the example weights. Prints per-example residuals (JSON); progress on stderr.",
        rig_opts},
       run_rig},
      {{"model build",
        "build the bilinear face model (core tensor + factors) into a file",
        "--from-face-model: bootstrap tensor from the face model (--identities random "
        "identities x 54 expressions, kept factored). --from-sessions: the rigs stored for "
        "sessions of --store (the newest rig made from each session, or the subject's newest rig "
        "without a session, as imports store them; sessions without a rig are skipped and listed), "
        "streamed from disk one subject at a time (Gram matrices accumulated, the tensor never "
        "held: ceil(subjects / panel) passes over the rigs plus one for the core). "
        "N-mode SVD without factoring the vertex mode, truncated to "
        "--id-knobs x --exp-knobs. File layout: algo/bilinear/README.md.",
        {{"from-face-model", "", "bootstrap from the face model", ""},
         {"from-sessions", "", "the rigs of stored sessions, streamed", ""},
         {"in-memory", "",
          "with --from-sessions: stack every rig in one dense tensor instead of streaming "
          "(the reference build; 7.3 MB a subject)",
          ""},
         {"memory-mb", "MB",
          "with --from-sessions: memory for the subjects held at once while streaming (7.3 MB "
          "each; more = fewer passes over the store)",
          "1024"},
         {"store", "DIR", "session store (with --from-sessions)", ""},
         {"sessions", "LIST", "session ids, comma-separated, or all", "all"},
         {"identities", "N", "sampled identities (with --from-face-model)", "150"},
         {"seed", "N", "identity sampling seed (with --from-face-model)", "1"},
         {"id-knobs", "N", "identity knobs kept", "50"},
         {"exp-knobs", "N", "expression knobs kept", "25"},
         {"out", "FILE", "model file to write (about 169 MB at 50 x 25)", ""}}},
       run_model_build},
  };
}

}  // namespace fb::cli
