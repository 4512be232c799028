// facebooth-lab eval rig | eval model: the rigging (algo/rigging) and the bilinear
// model (algo/bilinear) scored on synthetic subjects with known personal rigs; bench rig is in
// rig_bench.cpp
// (algo/rigging, FaceWarehouse 3.2.3) and the bilinear model (algo/bilinear, 3.3 and 4.1-4.4).
// JSON on stdout, progress on stderr.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include "algo/bilinear/bootstrap.hpp"
#include "algo/bilinear/image_fit.hpp"
#include "algo/core/clock.hpp"
#include "algo/fitting/expression_transfer.hpp"
#include "algo/rigging/example_rigging.hpp"
#include "host/cli/guide_files.hpp"
#include "host/cli/progress.hpp"
#include "host/cli/rig_session.hpp"
#include "host/cli/rig_support.hpp"
#include "host/cli/stats.hpp"
#include "sim/camera/synthetic_camera.hpp"
#include "sim/lab/lab_commands.hpp"
#include "sim/lab/rig_eval.hpp"
#include "sim/subject/synthetic_capture.hpp"
#include "storage/asset_files.hpp"
#include "storage/durable_file.hpp"

namespace fb::cli {
namespace {

// ---------------------------------------------------------------------------------------------
// facebooth-lab eval rig

// A synthetic subject's true personal rig (eval rig --truth): its neutral face(identity) and
// expression shapes, amplitude_j * basis_j, where basis is the model's generic deltas (linear,
// amplitude) or those deltas deformation-transferred onto the subject's neutral (transfer).
struct SubjectTruth {
  std::vector<float> neutral;
  std::vector<float> expression_basis;  // empty = the model's (generic) expression basis
  std::vector<float> amplitude;         // per model expression

  // amplitude_j w_j, one per model expression: the weights to render with this subject's basis.
  std::vector<float> scaled(std::span<const float> weights) const {
    std::vector<float> w(amplitude.size(), 0.0f);
    for (std::size_t j = 0; j < w.size() && j < weights.size(); ++j)
      w[j] = amplitude[j] * weights[j];
    return w;
  }

  // neutral + sum_j amplitude_j w_j basis_j
  std::vector<float> mesh(const FaceModel& model, std::span<const float> weights) const {
    const std::vector<float> w = scaled(weights);
    std::vector<float> out(neutral.size());
    if (expression_basis.empty()) {
      model.evaluate_expressions(neutral, w, out);
      return out;
    }
    out = neutral;
    for (std::size_t j = 0; j < w.size(); ++j) {
      if (w[j] == 0.0f) continue;
      const float* shape = expression_basis.data() + j * neutral.size();
      for (std::size_t i = 0; i < out.size(); ++i) out[i] += w[j] * shape[i];
    }
    return out;
  }
};

Result<SubjectTruth> subject_truth(const FaceModel& model, const std::vector<float>& identity,
                                   const std::string& kind, std::uint64_t seed) {
  SubjectTruth t;
  t.neutral = face(model, identity, {});
  t.amplitude.assign(static_cast<std::size_t>(model.expression_count), 1.0f);
  if (kind == "amplitude") {
    std::mt19937_64 krng(seed * 104729 + 3);
    std::uniform_real_distribution<float> k(0.6f, 1.4f);
    for (int j = 0; j < model.fitting_expression_count; ++j)
      t.amplitude[static_cast<std::size_t>(j)] = k(krng);
  }
  if (kind == "transfer") {
    // Sumner-Popovic deformation transfer G0 -> G_j onto this subject's neutral: each triangle
    // deforms as the generic one does, so a wide mouth opens wider than the generic delta.
    const std::vector<float> g0 = face(model, {}, {});
    auto transfer = ExpressionTransfer::create(model, t.neutral, g0);
    if (!transfer) return transfer.failure();
    const std::size_t n3 = t.neutral.size();
    t.expression_basis.assign(model.expression_basis.size(), 0.0f);
    std::vector<float> unit(static_cast<std::size_t>(model.expression_count), 0.0f);
    for (int j = 0; j < model.expression_count; ++j) {
      unit[static_cast<std::size_t>(j)] = 1.0f;
      auto shape = transfer->transfer(face(model, {}, unit));
      unit[static_cast<std::size_t>(j)] = 0.0f;
      if (!shape) return shape.failure();
      float* out = t.expression_basis.data() + static_cast<std::size_t>(j) * n3;
      for (std::size_t i = 0; i < n3; ++i) out[i] = (*shape)[i] - t.neutral[i];
    }
  }
  return t;
}

struct RigScore {
  Samples train, train_guide, train_truth, heldout, baseline, heldout_delta, baseline_delta,
      input_error, input_delta, guide_delta, seconds;
};

nlohmann::json score_json(const RigScore& s) {
  return {{"train_vertex_error_mm", s.train.mean()},
          {"train_vertex_error_mm_guide_weights", s.train_guide.mean()},
          {"train_vs_truth_vertex_error_mm", s.train_truth.mean()},
          {"heldout_vertex_error_mm", s.heldout.mean()},
          {"heldout_vertex_error_mm_worst_subject", s.heldout.max()},
          {"baseline_heldout_vertex_error_mm", s.baseline.mean()},
          {"heldout_expression_error_mm", s.heldout_delta.mean()},
          {"baseline_heldout_expression_error_mm", s.baseline_delta.mean()},
          {"input_vertex_error_mm", s.input_error.mean()},
          {"input_expression_error_mm", s.input_delta.mean()},
          {"baseline_train_expression_error_mm", s.guide_delta.mean()},
          {"rig_s_mean", s.seconds.mean()}};
}

// What every subject of eval rig is rigged and scored with.
struct RigEvalContext {
  const FaceModel& model;
  const RigOptions& rig_options;
  const RigInput& generic_input;
  const std::vector<std::vector<float>>& generic;  // generic[0]: the generic neutral
  std::span<const std::uint32_t> subset;
  int n = 0;  // fitting expressions
  long long mixes = 0;
};

// One subject: its true rig, the guide recipes' weights and the true meshes at them.
struct RigSubject {
  std::uint64_t seed = 0;
  SubjectTruth truth;
  std::vector<std::vector<float>> weights, truth_meshes;
};

// Rigs `examples` (fitted or true meshes of the guide expressions) and scores the rig against
// the subject's truth (through `to_truth`, the examples' frame -> the true model frame) on the
// training expressions and random held-out mixes, beside the naive baseline; adds to `score`.
Result<nlohmann::json> evaluate_examples(const RigEvalContext& ctx, const RigSubject& subject,
                                         const std::vector<std::vector<float>>& examples,
                                         const RigidPose& to_truth, RigScore& score,
                                         const char* label) {
  RigInput input = ctx.generic_input;
  for (const auto& m : examples) input.examples.emplace_back(m);
  input.example_weights = subject.weights;
  RigOptions o = ctx.rig_options;
  auto bar = std::make_shared<Progress>(std::string("eval rig: rigging (") + label + ")", 1000);
  o.progress = rig_progress(bar);
  auto rig = rig_subject(input, o);
  bar.reset();
  if (!rig) return rig.failure();
  Samples train, train_guide, train_truth, heldout, baseline, heldout_delta, baseline_delta,
      input_err, input_delta, guide_delta;
  for (std::size_t i = 1; i < examples.size(); ++i) {
    train.add(mean_distance(evaluate_rig(rig->neutral, rig->shapes, rig->weights[i]), examples[i],
                            ctx.subset));
    const auto at_guide = evaluate_rig(rig->neutral, rig->shapes, subject.weights[i]);
    train_guide.add(mean_distance(at_guide, examples[i], ctx.subset));
    train_truth.add(mean_distance(at_guide, subject.truth_meshes[i], ctx.subset, to_truth));
  }
  for (std::size_t i = 0; i < examples.size(); ++i)
    input_err.add(mean_distance(examples[i], subject.truth_meshes[i], ctx.subset, to_truth));
  // How much personal signal the examples carry: their expression parts against the truth's,
  // beside the generic deltas' error on the same expressions.
  for (std::size_t i = 1; i < examples.size(); ++i) {
    input_delta.add(mean_delta_distance(examples[i], examples[0], subject.truth_meshes[i],
                                        subject.truth_meshes[0], ctx.subset, to_truth.rotation));
    const auto generic_i = face(ctx.model, {}, subject.weights[i]);
    guide_delta.add(mean_delta_distance(generic_i, ctx.generic[0], subject.truth_meshes[i],
                                        subject.truth_meshes[0], ctx.subset, to_truth.rotation));
  }
  for (const auto& w : random_mixes(static_cast<int>(ctx.mixes), ctx.n, subject.seed * 31 + 7)) {
    const auto true_mesh = subject.truth.mesh(ctx.model, w);
    const auto rig_mesh = evaluate_rig(rig->neutral, rig->shapes, w);
    heldout.add(mean_distance(rig_mesh, true_mesh, ctx.subset, to_truth));
    // Naive baseline: the generic rig's deltas added to the subject's neutral example.
    std::vector<float> naive = examples[0];
    const auto generic_mix = face(ctx.model, {}, w);
    for (std::size_t k = 0; k < naive.size(); ++k) naive[k] += generic_mix[k] - ctx.generic[0][k];
    baseline.add(mean_distance(naive, true_mesh, ctx.subset, to_truth));
    // Both share the neutral example, so compare their expression parts alone as well.
    heldout_delta.add(mean_delta_distance(rig_mesh, rig->neutral, true_mesh, subject.truth.neutral,
                                          ctx.subset, to_truth.rotation));
    baseline_delta.add(mean_delta_distance(generic_mix, ctx.generic[0], true_mesh,
                                           subject.truth.neutral, ctx.subset, to_truth.rotation));
  }
  score.train.add(train.mean());
  score.train_guide.add(train_guide.mean());
  score.train_truth.add(train_truth.mean());
  score.heldout.add(heldout.mean());
  score.baseline.add(baseline.mean());
  score.heldout_delta.add(heldout_delta.mean());
  score.baseline_delta.add(baseline_delta.mean());
  score.input_error.add(input_err.mean());
  score.input_delta.add(input_delta.mean());
  score.guide_delta.add(guide_delta.mean());
  score.seconds.add(rig->seconds);
  std::fprintf(stderr,
               "  %s examples: train %.3f mm, held-out %.3f mm (baseline %.3f mm), "
               "expression part %.3f mm (baseline %.3f mm), input error %.3f mm (expression "
               "part %.3f mm; generic deltas there %.3f mm), rig %.2f s\n",
               label, train.mean(), heldout.mean(), baseline.mean(), heldout_delta.mean(),
               baseline_delta.mean(), input_err.mean(), input_delta.mean(), guide_delta.mean(),
               rig->seconds);
  return nlohmann::json{{"train_vertex_error_mm", train.mean()},
                        {"train_vs_truth_vertex_error_mm", train_truth.mean()},
                        {"heldout_vertex_error_mm", heldout.mean()},
                        {"baseline_heldout_vertex_error_mm", baseline.mean()},
                        {"heldout_expression_error_mm", heldout_delta.mean()},
                        {"baseline_heldout_expression_error_mm", baseline_delta.mean()},
                        {"input_vertex_error_mm", input_err.mean()},
                        {"input_expression_error_mm", input_delta.mean()},
                        {"baseline_train_expression_error_mm", guide_delta.mean()},
                        {"round_mean_residual_mm", rig->round_residual_mm},
                        {"rig_s", rig->seconds}};
}

// The fitting stage, as `eval fit` runs it: each guide expression captured (synthetic take ->
// fusion) and fitted (fit_neutral, fit_expression); the fitted meshes in the model frame, as the
// session store keeps them, and the fitted neutral's frame -> the true model frame.
Result<void> fit_examples(const FaceModel& model, const GuideSet& guide,
                          const RefineSystem& model_system, const std::vector<float>& identity,
                          const RigSubject& subject, int frames, double noise, std::mt19937_64& rng,
                          std::vector<std::vector<float>>& meshes, RigidPose& to_truth) {
  Progress bar("eval rig: subject " + std::to_string(subject.seed) + " captures + fits",
               static_cast<long long>(guide.expressions.size()));
  std::optional<ExpressionTransfer> transfer;
  std::vector<float> g0 = face(model, {}, {});
  for (const auto& ge : guide.expressions) {
    auto full = guide_weights(ge, model);
    if (!full) return full.failure();
    auto cap = capture(model, identity, subject.truth.scaled(*full),
                       subject.seed * 1000 + static_cast<std::uint64_t>(ge.id),
                       static_cast<int>(frames), false, subject.truth.expression_basis);
    if (!cap) return cap.failure();
    auto target = make_fit_target(*cap, noisy(cap->truth_color_px, noise, rng), false);
    if (!target) return target.failure();
    if (ge.id == 0) {
      auto fit = fit_neutral(model, *target, {}, nullptr, &model_system);
      if (!fit) return fit.failure();
      to_truth = cli::fitted_to_truth(*cap, fit->camera_from_model);
      auto tr = ExpressionTransfer::create(model, fit->vertices, g0);
      if (!tr) return tr.failure();
      transfer.emplace(std::move(*tr));
      meshes.push_back(fit->vertices);
    } else {
      auto gi = guide_mesh(ge, model);
      if (!gi) return gi.failure();
      auto parts = guide_part_meshes(ge, model);
      if (!parts) return parts.failure();
      auto fit = fit_expression(model, *transfer, *gi, *target, {}, std::nullopt, *parts);
      if (!fit) return fit.failure();
      // Model-frame vertices, as the session store keeps fitted meshes.
      meshes.push_back(fit->vertices);
    }
    bar.update(ge.id + 1);
  }
  return success();
}

// What each figure of eval rig means (`truth_kind`: the kind of true personal rig).
nlohmann::json rig_definitions(const std::string& truth_kind) {
  return {
      {"truth",
       truth_kind == "transfer"
           ? "personal rig B_j = the generic expression j deformation-transferred onto "
             "face(identity); examples = the 20 guide recipes on that subject"
       : truth_kind == "amplitude"
           ? "personal rig B_j = face(identity, k_j e_j), k_j ~ U(0.6, 1.4) per subject; "
             "examples = the 20 guide recipes on that subject"
           : "personal rig B_j = face(identity, e_j): the model's expression shapes on the "
             "subject's identity; examples = the 20 guide recipes on that subject"},
      {"train_vertex_error_mm",
       "rig at its re-estimated example weights vs the training meshes it was given"},
      {"train_vertex_error_mm_guide_weights", "the same at the guide recipes' weights"},
      {"train_vs_truth_vertex_error_mm", "rig at the guide weights vs the true expression"},
      {"heldout_vertex_error_mm",
       "random mixes (each shape on with p = 0.2, weight U(0,1)) vs the true mesh"},
      {"baseline_heldout_vertex_error_mm",
       "naive rig: generic deltas added to the subject's neutral example, same mixes"},
      {"heldout_expression_error_mm",
       "the expression part alone, |R (rig(w) - B_0) - (truth(w) - truth neutral)|: the rig and "
       "the baseline share the neutral example, whose fitting error otherwise dominates both"},
      {"baseline_heldout_expression_error_mm", "the same for the generic deltas"},
      {"input_vertex_error_mm", "the training meshes themselves vs the truth (fitting error)"},
      {"input_expression_error_mm",
       "the training meshes' expression parts (S_i - S_0) vs the truth's: the personal signal "
       "the examples carry is usable only where this is below the next figure"},
      {"baseline_train_expression_error_mm",
       "the generic deltas' expression parts vs the truth's, on the 19 training expressions"},
      {"region",
       "mean over the model's 7801 fitting vertices; fitted meshes are compared in "
       "the true model frame through the neutral fit's pose (as eval fit does)"}};
}

int run_eval_rig(const ParsedOptions& options) {
  auto subjects = options.get_int("subjects");
  auto first_seed = options.get_int("first-seed");
  auto frames = options.get_int("frames");
  auto noise = options.get_double("landmark-noise-px");
  auto mixes = options.get_int("mixes");
  if (!subjects || !first_seed || !frames || !noise || !mixes || *subjects < 1 || *frames < 2 ||
      *mixes < 1)
    return report_failure(
        {"--subjects >= 1, --frames >= 2, --mixes >= 1 (integers), "
         "--landmark-noise-px a number"});
  const std::string which = options.get("examples");
  if (which != "fitted" && which != "truth" && which != "both")
    return report_failure({"--examples must be fitted, truth or both"});
  const bool use_fitted = which != "truth", use_truth = which != "fitted";
  const std::string truth_kind = options.get("truth");
  if (truth_kind != "linear" && truth_kind != "amplitude" && truth_kind != "transfer")
    return report_failure({"--truth must be linear, amplitude or transfer"});
  auto model = load_face_model();
  if (!model) return report_failure(model.error());
  auto guide = load_guide(*model, options.get("guide"));
  if (!guide) return report_failure(guide.error());
  auto model_system = model_refine_system(*model);
  if (!model_system) return report_failure(model_system.error());
  auto rig_opts = rig_options(options, *model);
  if (!rig_opts) return report_failure(rig_opts.error());
  const int n = model->fitting_expression_count;
  const auto subset = std::span<const std::uint32_t>(model->fitting_vertices);
  std::vector<std::vector<float>> generic;
  const RigInput generic_input = generic_rig_input(*model, generic);

  const RigEvalContext ctx{*model, *rig_opts, generic_input, generic, subset, n, *mixes};
  RigScore fitted_score, truth_score;
  nlohmann::json per_subject = nlohmann::json::array();
  for (long long s = 0; s < *subjects; ++s) {
    const std::uint64_t seed = static_cast<std::uint64_t>(*first_seed + s);
    const auto identity = identity_draw(seed, model->identity_count);
    std::mt19937_64 rng(seed * 7919 + 17);
    auto truth = subject_truth(*model, identity, truth_kind, seed);
    if (!truth) return report_failure(truth.error());
    RigSubject subject_data{seed, std::move(*truth), {}, {}};
    for (const auto& ge : guide->expressions) {
      auto w = guide_weights(ge, *model);
      if (!w) return report_failure(w.error());
      w->resize(static_cast<std::size_t>(n));
      subject_data.weights.push_back(*w);
      subject_data.truth_meshes.push_back(subject_data.truth.mesh(*model, *w));
    }
    nlohmann::json subject{{"seed", seed}};
    RigidPose fitted_to_truth;  // fitted neutral's model frame -> the true model frame
    std::vector<std::vector<float>> fitted_meshes;
    if (use_fitted) {
      if (auto ok =
              fit_examples(*model, *guide, *model_system, identity, subject_data,
                           static_cast<int>(*frames), *noise, rng, fitted_meshes, fitted_to_truth);
          !ok)
        return report_failure(ok.error());
    }
    if (use_fitted) {
      auto j = evaluate_examples(ctx, subject_data, fitted_meshes, fitted_to_truth, fitted_score,
                                 "fitted");
      if (!j) return report_failure(j.error());
      subject["fitted_examples"] = *j;
    }
    if (use_truth) {
      auto j = evaluate_examples(ctx, subject_data, subject_data.truth_meshes, RigidPose{},
                                 truth_score, "ground-truth");
      if (!j) return report_failure(j.error());
      subject["truth_examples"] = *j;
    }
    per_subject.push_back(subject);
  }
  const RigScore& primary = use_fitted ? fitted_score : truth_score;
  nlohmann::json out = score_json(primary);
  out["examples"] = use_fitted ? "fitted meshes from the fitting stage" : "ground-truth meshes";
  if (use_fitted && use_truth) out["with_truth_examples"] = score_json(truth_score);
  out["subjects"] = *subjects;
  out["frames_per_capture"] = *frames;
  out["landmark_noise_px"] = *noise;
  out["heldout_mixes_per_subject"] = *mixes;
  out["truth"] = truth_kind;
  out["definitions"] = rig_definitions(truth_kind);
  out["targets"] = {{"train_vertex_error_mm", 0.5}, {"heldout_vertex_error_mm", 1.0}};
  out["meets_targets"] = primary.train.mean() <= 0.5 && primary.heldout.mean() <= 1.0;
  out["per_subject"] = per_subject;
  std::cout << out.dump(2) << std::endl;
  return kExitOk;
}

}  // namespace

std::vector<Command> rig_eval_commands() {
  const OptionSpec guide_opt{"guide", "FILE",
                             "guide recipes (default: DATA_DIR/guide_expressions.json)", ""};
  const OptionSpec json_opt{"json", "", "JSON report on stdout (the only output format)", ""};
  std::vector<OptionSpec> eval_rig_opts = {
      {"subjects", "N", "synthetic subjects", "2"},
      {"first-seed", "N", "seed of the first subject (identity drawn as eval fit does)", "1"},
      {"frames", "N", "frames per head-turn take fused", "45"},
      landmark_noise_option(),
      {"mixes", "N", "held-out random expression mixes per subject", "20"},
      {"truth", "linear|amplitude|transfer",
       "true personal rig: linear = the model's expression shapes on the subject's identity (the "
       "naive baseline is then exact up to the neutral's error); amplitude = each shape also "
       "scaled by a per-subject factor in [0.6, 1.4]; transfer = the generic expressions "
       "deformation-transferred onto the subject's neutral, so personal deltas follow the "
       "subject's geometry",
       "transfer"},
      {"examples", "fitted|truth|both",
       "train on fitted meshes from the fitting stage, on the exact meshes, or both (the "
       "headline keys are from the fitted run unless truth alone is asked)",
       "both"},
      guide_opt,
      json_opt};
  for (const auto& o : rig_option_specs()) eval_rig_opts.push_back(o);
  return {
      {{"eval rig", "score rigging on synthetic subjects with known personal rigs (JSON on stdout)",
        "Per subject: the 20 guide expressions are captured (synthetic take -> fusion) and fitted "
        "as `eval fit` does, the fitted meshes are rigged, and the rig is compared with the true "
        "personal rig (see --truth) on the training expressions and on random held-out mixes, next "
        "to the naive baseline (generic deltas on the subject's neutral), over whole faces and "
        "over "
        "their expression parts alone (the two share the neutral example). With --examples both "
        "the rig is also trained on the exact meshes, which separates the rig's own error from "
        "the fitting's. About 40 s per subject.",
        eval_rig_opts},
       run_eval_rig},
      {{"eval model",
        "score the bilinear model: held-out reconstruction vs knobs, landmark fitting (JSON)",
        "Builds the bootstrap model in memory, reconstructs held-out synthetic subjects for a "
        "table of knob counts (FaceWarehouse Fig. 4), and fits the default-knob model to the "
        "landmarks of held-out synthetic images, one image at a time and jointly.",
        {{"identities", "N", "identities in the bootstrap tensor", "150"},
         {"heldout", "N", "held-out subjects", "10"},
         {"seed", "N", "identity sampling seed", "1"},
         {"images", "N", "images per held-out subject for the landmark fits (joint fit if > 1)",
          "3"},
         landmark_noise_option(),
         {"plot", "FILE.png", "write the error-vs-knobs plot (OpenCV)", ""},
         {"model", "FILE",
          "fit the landmarks with this model file (from `model build`) instead of the in-memory "
          "bootstrap at 50 x 25",
          ""},
         guide_opt,
         json_opt}},
       run_eval_model},
  };
}

}  // namespace fb::cli
