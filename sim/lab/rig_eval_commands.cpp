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

  RigScore fitted_score, truth_score;
  nlohmann::json per_subject = nlohmann::json::array();
  for (long long s = 0; s < *subjects; ++s) {
    const std::uint64_t seed = static_cast<std::uint64_t>(*first_seed + s);
    const auto identity = identity_draw(seed, model->identity_count);
    std::mt19937_64 rng(seed * 7919 + 17);
    auto truth = subject_truth(*model, identity, truth_kind, seed);
    if (!truth) return report_failure(truth.error());
    std::vector<std::vector<float>> weights, truth_meshes, fitted_meshes;
    for (const auto& ge : guide->expressions) {
      auto w = guide_weights(ge, *model);
      if (!w) return report_failure(w.error());
      w->resize(static_cast<std::size_t>(n));
      weights.push_back(*w);
      truth_meshes.push_back(truth->mesh(*model, *w));
    }
    nlohmann::json subject{{"seed", seed}};
    RigidPose fitted_to_truth;  // fitted neutral's model frame -> the true model frame
    if (use_fitted) {
      // The fitting stage, as `eval fit` runs it: capture -> fusion -> fit_neutral /
      // fit_expression.
      Progress bar("eval rig: subject " + std::to_string(seed) + " captures + fits",
                   static_cast<long long>(guide->expressions.size()));
      std::optional<ExpressionTransfer> transfer;
      std::vector<float> g0 = face(*model, {}, {});
      for (const auto& ge : guide->expressions) {
        auto full = guide_weights(ge, *model);
        if (!full) return report_failure(full.error());
        auto cap = capture(*model, identity, truth->scaled(*full),
                           seed * 1000 + static_cast<std::uint64_t>(ge.id),
                           static_cast<int>(*frames), false, truth->expression_basis);
        if (!cap) return report_failure(cap.error());
        auto target = make_fit_target(*cap, noisy(cap->truth_color_px, *noise, rng), false);
        if (!target) return report_failure(target.error());
        if (ge.id == 0) {
          auto fit = fit_neutral(*model, *target, {}, nullptr, &*model_system);
          if (!fit) return report_failure(fit.error());
          fitted_to_truth = cli::fitted_to_truth(*cap, fit->camera_from_model);
          auto tr = ExpressionTransfer::create(*model, fit->vertices, g0);
          if (!tr) return report_failure(tr.error());
          transfer.emplace(std::move(*tr));
          fitted_meshes.push_back(fit->vertices);
        } else {
          auto gi = guide_mesh(ge, *model);
          if (!gi) return report_failure(gi.error());
          auto fit = fit_expression(*model, *transfer, *gi, *target);
          if (!fit) return report_failure(fit.error());
          // Model-frame vertices, as the session store keeps fitted meshes.
          fitted_meshes.push_back(fit->vertices);
        }
        bar.update(ge.id + 1);
      }
    }
    auto evaluate = [&](const std::vector<std::vector<float>>& examples, const RigidPose& to_truth,
                        RigScore& score, const char* label) -> Result<nlohmann::json> {
      RigInput input = generic_input;
      for (const auto& m : examples) input.examples.emplace_back(m);
      input.example_weights = weights;
      RigOptions o = *rig_opts;
      auto bar = std::make_shared<Progress>(std::string("eval rig: rigging (") + label + ")", 1000);
      o.progress = rig_progress(bar);
      auto rig = rig_subject(input, o);
      bar.reset();
      if (!rig) return rig.failure();
      Samples train, train_guide, train_truth, heldout, baseline, heldout_delta, baseline_delta,
          input_err, input_delta, guide_delta;
      for (std::size_t i = 1; i < examples.size(); ++i) {
        train.add(mean_distance(evaluate_rig(rig->neutral, rig->shapes, rig->weights[i]),
                                examples[i], subset));
        const auto at_guide = evaluate_rig(rig->neutral, rig->shapes, weights[i]);
        train_guide.add(mean_distance(at_guide, examples[i], subset));
        train_truth.add(mean_distance(at_guide, truth_meshes[i], subset, to_truth));
      }
      for (std::size_t i = 0; i < examples.size(); ++i)
        input_err.add(mean_distance(examples[i], truth_meshes[i], subset, to_truth));
      // How much personal signal the examples carry: their expression parts against the truth's,
      // beside the generic deltas' error on the same expressions.
      for (std::size_t i = 1; i < examples.size(); ++i) {
        input_delta.add(mean_delta_distance(examples[i], examples[0], truth_meshes[i],
                                            truth_meshes[0], subset, to_truth.rotation));
        const auto generic_i = face(*model, {}, weights[i]);
        guide_delta.add(mean_delta_distance(generic_i, generic[0], truth_meshes[i], truth_meshes[0],
                                            subset, to_truth.rotation));
      }
      for (const auto& w : random_mixes(static_cast<int>(*mixes), n, seed * 31 + 7)) {
        const auto true_mesh = truth->mesh(*model, w);
        const auto rig_mesh = evaluate_rig(rig->neutral, rig->shapes, w);
        heldout.add(mean_distance(rig_mesh, true_mesh, subset, to_truth));
        // Naive baseline: the generic rig's deltas added to the subject's neutral example.
        std::vector<float> naive = examples[0];
        const auto generic_mix = face(*model, {}, w);
        for (std::size_t k = 0; k < naive.size(); ++k) naive[k] += generic_mix[k] - generic[0][k];
        baseline.add(mean_distance(naive, true_mesh, subset, to_truth));
        // Both share the neutral example, so compare their expression parts alone as well.
        heldout_delta.add(mean_delta_distance(rig_mesh, rig->neutral, true_mesh, truth->neutral,
                                              subset, to_truth.rotation));
        baseline_delta.add(mean_delta_distance(generic_mix, generic[0], true_mesh, truth->neutral,
                                               subset, to_truth.rotation));
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
    };
    if (use_fitted) {
      auto j = evaluate(fitted_meshes, fitted_to_truth, fitted_score, "fitted");
      if (!j) return report_failure(j.error());
      subject["fitted_examples"] = *j;
    }
    if (use_truth) {
      auto j = evaluate(truth_meshes, RigidPose{}, truth_score, "ground-truth");
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
  out["definitions"] = {
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
  out["targets"] = {{"train_vertex_error_mm", 0.5}, {"heldout_vertex_error_mm", 1.0}};
  out["meets_targets"] = primary.train.mean() <= 0.5 && primary.heldout.mean() <= 1.0;
  out["per_subject"] = per_subject;
  std::cout << out.dump(2) << std::endl;
  return kExitOk;
}

// ---------------------------------------------------------------------------------------------
// facebooth-lab eval model

struct KnobCell {
  int id_knobs = 0, exp_knobs = 0;
  double error_mm = 0;
};

// Held-out reconstruction in the factored tensor's coefficient space: for subject s with true
// slices basis * a(s, e), w_id minimises sum_e |basis_f (M_e w - a(s, e))|^2 over the fitting
// vertices (Gram G), M_e = sum_b U~_exp[e, b] Ccoef_b; the error is the mean vertex distance of
// basis (M_e w - a(s, e)) over `error_rows` (a vertex subset), averaged over e and subjects.
double heldout_error(const FactoredTensor& train, const ModeFactors& factors,
                     const Eigen::MatrixXd& gram, const Eigen::MatrixXd& error_basis,
                     const std::vector<std::vector<float>>& heldout_ids, int id_knobs,
                     int exp_knobs) {
  const Eigen::MatrixXd u_exp = factors.expression.leftCols(exp_knobs);
  const Eigen::MatrixXd ccoef =
      factored_core(train, factors.identity.leftCols(id_knobs), u_exp);  // K x (b * a)
  const Eigen::MatrixXd g_ccoef = gram * ccoef;
  const Eigen::Index k = ccoef.rows();
  const int n_exp = train.expressions;
  const int n_modes = static_cast<int>(heldout_ids.front().size());
  std::vector<Eigen::MatrixXd> m(static_cast<std::size_t>(n_exp)), gm(m.size());
  for (int e = 0; e < n_exp; ++e) {
    m[e] = Eigen::MatrixXd::Zero(k, id_knobs);
    gm[e] = Eigen::MatrixXd::Zero(k, id_knobs);
    for (int b = 0; b < exp_knobs; ++b) {
      m[e] += u_exp(e, b) * ccoef.middleCols(static_cast<Eigen::Index>(b) * id_knobs, id_knobs);
      gm[e] += u_exp(e, b) * g_ccoef.middleCols(static_cast<Eigen::Index>(b) * id_knobs, id_knobs);
    }
  }
  Eigen::MatrixXd h = Eigen::MatrixXd::Zero(id_knobs, id_knobs);
  for (int e = 0; e < n_exp; ++e) h.noalias() += m[e].transpose() * gm[e];
  h.diagonal().array() += 1e-9 * h.diagonal().mean();
  const Eigen::LDLT<Eigen::MatrixXd> solver(h);
  const Eigen::Index rows = error_basis.rows() / 3;
  double total = 0;
  for (const auto& c : heldout_ids) {
    Eigen::MatrixXd a = Eigen::MatrixXd::Zero(k, n_exp);
    for (int e = 0; e < n_exp; ++e) {
      a(0, e) = 1.0;
      for (int q = 0; q < n_modes; ++q) a(1 + q, e) = c[static_cast<std::size_t>(q)];
      if (e > 0) a(n_modes + e, e) = 1.0;
    }
    Eigen::VectorXd g = Eigen::VectorXd::Zero(id_knobs);
    for (int e = 0; e < n_exp; ++e) g.noalias() += gm[e].transpose() * a.col(e);
    const Eigen::VectorXd w = solver.solve(g);
    Eigen::MatrixXd residual(k, n_exp);
    for (int e = 0; e < n_exp; ++e) residual.col(e) = m[e] * w - a.col(e);
    const Eigen::MatrixXd d = error_basis * residual;  // (3 rows) x E
    double s = 0;
    for (int e = 0; e < n_exp; ++e)
      for (Eigen::Index v = 0; v < rows; ++v) s += d.block<3, 1>(3 * v, e).norm();
    total += s / (static_cast<double>(rows) * n_exp);
  }
  return total / static_cast<double>(heldout_ids.size());
}

Eigen::MatrixXd basis_rows(const FactoredTensor& t, std::span<const std::uint32_t> vertices,
                           int stride) {
  std::vector<std::uint32_t> use;
  for (std::size_t i = 0; i < vertices.size(); i += static_cast<std::size_t>(stride))
    use.push_back(vertices[i]);
  Eigen::MatrixXd out(3 * static_cast<Eigen::Index>(use.size()), t.basis.cols());
  for (std::size_t i = 0; i < use.size(); ++i)
    out.middleRows(3 * static_cast<Eigen::Index>(i), 3) =
        t.basis.middleRows(3 * static_cast<Eigen::Index>(use[i]), 3).cast<double>();
  return out;
}

Result<void> write_knob_plot(const std::filesystem::path& path, const std::vector<KnobCell>& cells,
                             const std::vector<int>& id_list, const std::vector<int>& exp_list,
                             int identities, int heldout) {
  const int w = 900, h = 600, left = 80, right = 190, top = 60, bottom = 70;
  cv::Mat img(h, w, CV_8UC3, cv::Scalar(255, 255, 255));
  double ymax = 0;
  for (const auto& c : cells) ymax = std::max(ymax, c.error_mm);
  ymax = std::max(0.5, std::ceil(ymax * 2) / 2);
  const double xmax = *std::max_element(id_list.begin(), id_list.end());
  auto px = [&](double x, double y) {
    return cv::Point(left + static_cast<int>(x / xmax * (w - left - right)),
                     h - bottom - static_cast<int>(y / ymax * (h - top - bottom)));
  };
  const cv::Scalar black(0, 0, 0), grey(210, 210, 210);
  for (int k = 0; k <= 10; ++k) {
    const double y = ymax * k / 10;
    cv::line(img, px(0, y), px(xmax, y), grey, 1);
    char t[32];
    std::snprintf(t, sizeof t, "%.2f", y);
    cv::putText(img, t, px(0, y) + cv::Point(-58, 5), cv::FONT_HERSHEY_SIMPLEX, 0.45, black, 1,
                cv::LINE_AA);
  }
  for (int x : id_list) {
    cv::line(img, px(x, 0), px(x, 0) + cv::Point(0, 6), black, 1);
    cv::putText(img, std::to_string(x), px(x, 0) + cv::Point(-10, 24), cv::FONT_HERSHEY_SIMPLEX,
                0.45, black, 1, cv::LINE_AA);
  }
  cv::line(img, px(0, 0), px(xmax, 0), black, 1);
  cv::line(img, px(0, 0), px(0, ymax), black, 1);
  cv::putText(img, "identity knobs", cv::Point(w / 2 - 80, h - 20), cv::FONT_HERSHEY_SIMPLEX, 0.6,
              black, 1, cv::LINE_AA);
  cv::putText(img, "mean vertex error (mm)", cv::Point(10, top - 20), cv::FONT_HERSHEY_SIMPLEX,
              0.55, black, 1, cv::LINE_AA);
  char title[200];
  std::snprintf(title, sizeof title,
                "Held-out reconstruction vs knobs (bootstrap, %d identities, %d held out)",
                identities, heldout);
  cv::putText(img, title, cv::Point(left, 25), cv::FONT_HERSHEY_SIMPLEX, 0.6, black, 1,
              cv::LINE_AA);
  for (std::size_t k = 0; k < exp_list.size(); ++k) {
    cv::Mat hue(1, 1, CV_8UC3, cv::Scalar(static_cast<int>(150.0 * k / exp_list.size()), 220, 200));
    cv::Mat bgr;
    cv::cvtColor(hue, bgr, cv::COLOR_HSV2BGR);
    const cv::Vec3b c = bgr.at<cv::Vec3b>(0, 0);
    const cv::Scalar colour(c[0], c[1], c[2]);
    std::vector<cv::Point> line;
    for (const auto& cell : cells)
      if (cell.exp_knobs == exp_list[k]) line.push_back(px(cell.id_knobs, cell.error_mm));
    cv::polylines(img, line, false, colour, 2, cv::LINE_AA);
    for (const auto& p : line) cv::circle(img, p, 4, colour, cv::FILLED, cv::LINE_AA);
    const cv::Point at(w - right + 20, top + 25 * static_cast<int>(k));
    cv::line(img, at, at + cv::Point(30, 0), colour, 2, cv::LINE_AA);
    cv::putText(img, std::to_string(exp_list[k]) + " exp knobs", at + cv::Point(38, 5),
                cv::FONT_HERSHEY_SIMPLEX, 0.5, black, 1, cv::LINE_AA);
  }
  for (const auto& cell : cells)
    if (cell.id_knobs == 50 && cell.exp_knobs == 25) {
      cv::circle(img, px(50, cell.error_mm), 9, black, 1, cv::LINE_AA);
      cv::putText(img, "default 50 x 25", px(50, cell.error_mm) + cv::Point(12, -10),
                  cv::FONT_HERSHEY_SIMPLEX, 0.45, black, 1, cv::LINE_AA);
    }
  try {
    if (!cv::imwrite(path.string(), img)) return fail("could not write " + path.string());
  } catch (const cv::Exception& e) {
    return fail("could not write " + path.string() + ": " + e.what());
  }
  return success();
}

// Similarity-aligned mean distance (weak perspective does not observe absolute size or depth).
double similarity_distance(std::span<const float> a, std::span<const float> b,
                           std::span<const std::uint32_t> subset) {
  Eigen::Matrix3Xd src(3, subset.size()), dst(3, subset.size());
  for (std::size_t i = 0; i < subset.size(); ++i) {
    const auto v = subset[i];
    src.col(static_cast<Eigen::Index>(i)) << a[3 * v], a[3 * v + 1], a[3 * v + 2];
    dst.col(static_cast<Eigen::Index>(i)) << b[3 * v], b[3 * v + 1], b[3 * v + 2];
  }
  const Eigen::Matrix4d t = Eigen::umeyama(src, dst, true);
  const Eigen::Matrix3Xd moved =
      (t.topLeftCorner<3, 3>() * src).colwise() + t.topRightCorner<3, 1>();
  return (moved - dst).colwise().norm().mean();
}

int run_eval_model(const ParsedOptions& options) {
  auto identities = options.get_int("identities");
  auto heldout = options.get_int("heldout");
  auto seed = options.get_int("seed");
  auto noise = options.get_double("landmark-noise-px");
  auto images = options.get_int("images");
  if (!identities || !heldout || !seed || !noise || !images || *identities < 2 || *heldout < 1 ||
      *images < 1)
    return report_failure({"--identities >= 2, --heldout >= 1, --images >= 1 (integers)"});
  auto face_model = load_face_model();
  if (!face_model) return report_failure(face_model.error());
  auto guide = load_guide(*face_model, options.get("guide"));
  if (!guide) return report_failure(guide.error());
  nlohmann::json out;

  // 1. Reconstruction of held-out subjects vs knob counts (Fig. 4).
  std::cerr << "eval model: decomposing the bootstrap tensor (" << *identities
            << " identities)...\n";
  const auto t0 = Clock::now();
  const auto train_ids = draw_identities(*face_model, static_cast<int>(*identities),
                                         static_cast<std::uint64_t>(*seed));
  const FactoredTensor tensor = bootstrap_tensor(*face_model, train_ids);
  auto factors = mode_factors(tensor);
  if (!factors) return report_failure(factors.error());
  out["decomposition_s"] = seconds_since(t0);
  const auto test_ids = draw_identities(*face_model, static_cast<int>(*heldout),
                                        static_cast<std::uint64_t>(*seed) + 1000003);
  const Eigen::MatrixXd fit_basis = basis_rows(tensor, face_model->fitting_vertices, 1);
  const Eigen::MatrixXd gram = fit_basis.transpose() * fit_basis;
  const Eigen::MatrixXd coarse_basis = basis_rows(tensor, face_model->fitting_vertices, 8);
  std::vector<int> id_list, exp_list;
  for (int a : {5, 10, 20, 30, 50, 75, 100, 150})
    if (a <= tensor.identities) id_list.push_back(a);
  for (int b : {5, 10, 15, 25, 40, 54})
    if (b <= tensor.expressions) exp_list.push_back(b);
  std::vector<KnobCell> cells;
  nlohmann::json table = nlohmann::json::array();
  Progress bar("eval model: knob table", static_cast<long long>(id_list.size() * exp_list.size()));
  for (int b : exp_list)
    for (int a : id_list) {
      const double e = heldout_error(tensor, *factors, gram, coarse_basis, test_ids, a, b);
      cells.push_back({a, b, e});
      table.push_back({{"id_knobs", a}, {"exp_knobs", b}, {"heldout_reconstruction_mm", e}});
      bar.update(static_cast<long long>(cells.size()));
    }
  const int def_id = std::min(50, tensor.identities), def_exp = std::min(25, tensor.expressions);
  out["heldout_reconstruction_mm"] =
      heldout_error(tensor, *factors, gram, fit_basis, test_ids, def_id, def_exp);
  out["default_knobs"] = {def_id, def_exp};
  out["reconstruction_table"] = table;
  out["reconstruction_definition"] =
      "held-out subjects (identities not in the tensor, same 54 expressions): w_id by least "
      "squares over all 54 expressions with w_exp = the model's U_exp rows; mean vertex distance "
      "over the fitting vertices (table: every 8th fitting vertex; headline: all 7801)";
  if (!options.get("plot").empty()) {
    if (auto ok = write_knob_plot(options.get("plot"), cells, id_list, exp_list, tensor.identities,
                                  static_cast<int>(*heldout));
        !ok)
      return report_failure(ok.error());
    out["plot"] = std::filesystem::absolute(options.get("plot")).string();
  }

  // 2. Landmark fit on held-out synthetic images (the synthetic camera's perspective renders).
  BilinearModel model;
  if (const std::string file = options.get("model"); !file.empty()) {
    auto bytes = read_file_bytes(file);
    if (!bytes) return report_failure(bytes.error());
    auto parsed = parse_bilinear_model(std::as_bytes(std::span(*bytes)));
    if (!parsed) return report_failure({file + ": " + parsed.error().message});
    if (parsed->vertex_count != face_model->vertex_count)
      return report_failure({file + ": the model has " + std::to_string(parsed->vertex_count) +
                             " vertices, the face model " +
                             std::to_string(face_model->vertex_count)});
    model = std::move(*parsed);
    out["landmark_fit_model"] = std::filesystem::absolute(file).string();
  } else {
    auto built = truncate(tensor, *factors, def_id, def_exp);
    if (!built) return report_failure(built.error());
    model = make_bilinear_model(*built, *face_model, bootstrap_expression_names(*face_model), "{}");
    out["landmark_fit_model"] = "bootstrap built in memory at the default knobs";
  }
  Samples fit_px, fit_truth_px, joint_px, mesh_mm, joint_mesh_mm, fit_ms;
  std::mt19937_64 rng(static_cast<std::uint64_t>(*seed) * 13 + 5);
  const int per_subject = static_cast<int>(*images);
  Progress lbar("eval model: landmark fits", static_cast<long long>(test_ids.size()));
  for (std::size_t s = 0; s < test_ids.size(); ++s) {
    const auto& ge = guide->expressions[1 + s % (guide->expressions.size() - 1)];
    auto w = guide_weights(ge, *face_model);
    if (!w) return report_failure(w.error());
    SyntheticOptions so;
    so.seed = 500 + s;
    so.identity_coeffs = test_ids[s];
    so.expression_weights = *w;
    so.frame_count = 8 * per_subject;
    auto camera = make_synthetic_camera(*face_model, so);
    if (!camera) return report_failure(camera.error());
    if (auto ok = (*camera)->start(); !ok) return report_failure(ok.error());
    std::vector<ImageLandmarks> shots, truths;
    RgbdFrame frame;
    const auto truth_mesh = face(*face_model, test_ids[s], *w);
    for (int f = 0; f < 8 * per_subject; ++f) {
      auto st = (*camera)->next_frame(frame, std::chrono::milliseconds(1000));
      if (!st) return report_failure(st.error());
      if (f % 8 != 0) continue;
      const FrameTruth* t = frame_truth(**camera);
      if (!t) return report_failure({"the synthetic camera gave no ground truth"});
      ImageLandmarks l, lt;
      const auto noisy_px = noisy(t->landmarks_color_px, *noise, rng);
      for (int k = 0; k < 68; ++k) {
        l.points[k] = noisy_px[k];
        lt.points[k] = t->landmarks_color_px[k];
        l.valid[k] = lt.valid[k] = true;
      }
      shots.push_back(l);
      truths.push_back(lt);
    }
    auto score = [&](const LandmarkFit& fit, std::span<const float> w_id, const ImageLandmarks& l,
                     const ImageLandmarks& lt, Samples& given, Samples* vs_truth, Samples& mesh) {
      std::vector<float> mesh_fit(static_cast<std::size_t>(model.coordinate_count()));
      model.evaluate(w_id, fit.w_exp, mesh_fit);
      double sg = 0, st = 0;
      for (int k = 0; k < 68; ++k) {
        const auto v = model.landmark_vertices[k];
        const Eigen::Vector2d p =
            fit.pose.project({mesh_fit[3 * v], mesh_fit[3 * v + 1], mesh_fit[3 * v + 2]});
        sg += (p - l.points[k]).norm();
        st += (p - lt.points[k]).norm();
      }
      given.add(sg / 68);
      if (vs_truth) vs_truth->add(st / 68);
      mesh.add(similarity_distance(mesh_fit, truth_mesh, face_model->fitting_vertices));
    };
    for (std::size_t i = 0; i < shots.size(); ++i) {
      const auto t1 = Clock::now();
      auto fit = fit_landmarks(model, shots[i]);
      fit_ms.add(seconds_since(t1) * 1000);
      if (!fit) return report_failure(fit.error());
      score(*fit, fit->w_id, shots[i], truths[i], fit_px, &fit_truth_px, mesh_mm);
    }
    if (shots.size() > 1) {
      auto joint = fit_landmarks_joint(model, shots);
      if (!joint) return report_failure(joint.error());
      for (std::size_t i = 0; i < shots.size(); ++i)
        score(joint->images[i], joint->w_id, shots[i], truths[i], joint_px, nullptr, joint_mesh_mm);
    }
    lbar.update(static_cast<long long>(s + 1));
  }
  out["landmark_fit_error_px"] = fit_px.mean();
  out["landmark_fit_error_vs_true_points_px"] = fit_truth_px.mean();
  out["landmark_fit_mesh_error_mm_similarity_aligned"] = mesh_mm.mean();
  out["landmark_fit_ms"] = fit_ms.mean();
  if (!joint_px.empty()) {
    out["joint_fit_images"] = per_subject;
    out["joint_landmark_fit_error_px"] = joint_px.mean();
    out["joint_fit_mesh_error_mm_similarity_aligned"] = joint_mesh_mm.mean();
  }
  out["landmark_fit_definition"] =
      "held-out subjects rendered by the synthetic camera (perspective, head turn; frames 0, 8, "
      "16, ...), one guide expression each; input = the true colour-image landmarks + Gaussian "
      "noise of landmark_noise_px per axis; error = mean distance of the fitted model's projected "
      "landmarks (weak perspective, coordinate descent, default knobs) to the input points; "
      "mesh error after a similarity alignment over the fitting vertices";
  out["landmark_noise_px"] = *noise;
  out["identities"] = *identities;
  out["heldout_subjects"] = *heldout;
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
      {"landmark-noise-px", "PX", "Gaussian noise on the true landmarks (per axis)", "1"},
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
         {"landmark-noise-px", "PX", "Gaussian noise on the true landmarks (per axis)", "1"},
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
