// facebooth-lab bench fit: time landmarks (dlib, full image and tracked), the neutral fit and
// the expression fits on one synthetic subject, best of --repeats.
#include <algorithm>
#include <iostream>

#include "algo/core/clock.hpp"
#include "algo/fitting/expression_transfer.hpp"
#include "host/cli/guide_files.hpp"
#include "sim/lab/fit_eval_parts.hpp"
#include "storage/asset_files.hpp"

namespace fb::cli::fit_eval {

int run_bench_fit(const ParsedOptions& options) {
  auto seed = options.get_int("seed");
  if (!seed) return report_failure(seed.error());
  auto repeats = options.get_int("repeats");
  if (!repeats || *repeats < 1) return report_failure({"--repeats must be at least 1"});
  auto model = load_face_model();
  if (!model) return report_failure(model.error());
  auto guide = load_guide(*model, options.get("guide"));
  if (!guide) return report_failure(guide.error());
  const std::vector<float> identity =
      identity_draw(static_cast<std::uint64_t>(*seed), model->identity_count);
  nlohmann::json out;
  std::cerr << "bench fit: captures (synthetic + fusion)...\n";
  auto neutral_cap = capture(*model, identity, {}, 1, 30, true);
  if (!neutral_cap) return report_failure(neutral_cap.error());
  // Landmarks: full-image detection once, then tracked frames.
  if (options.get("dlib") != "off") {
    auto det = load_detector(options.get("shape-predictor"));
    if (!det) return report_failure(det.error());
    Samples full, tracked;
    for (long long r = 0; r < *repeats; ++r) {
      det->reset_tracking();
      const auto t0 = Clock::now();
      auto f = det->detect(neutral_cap->colors.front());
      full.add(ms_since(t0));
      if (!f) return report_failure(f.error());
      for (std::size_t i = 1; i < neutral_cap->colors.size(); ++i) {
        const auto t1 = Clock::now();
        auto t = det->detect(neutral_cap->colors[i]);
        if (t && t->tracked) tracked.add(ms_since(t1));
      }
    }
    out["landmark_ms"] = tracked.mean();
    out["landmark_ms_full_image"] = full.mean();
    out["landmark_tracked_frames"] = tracked.size();
  }
  auto target = make_fit_target(*neutral_cap, neutral_cap->truth_color_px, false);
  if (!target) return report_failure(target.error());
  double best_neutral = 1e30, best_step1 = 0, best_refine = 0;
  // Once per model (the daemon would do it at start): the mean face's refinement matrix.
  const auto ms0 = Clock::now();
  auto model_system = model_refine_system(*model);
  if (!model_system) return report_failure(model_system.error());
  out["model_refine_factorization_ms"] = ms_since(ms0);
  FitResult neutral;
  // The same fit without the offsets along the normal (NeutralFitOptions::offset_amplitude_mm),
  // alternating with it: what they cost.
  NeutralFitOptions no_offsets;
  no_offsets.offset_amplitude_mm = 0;
  double best_no_offsets = 1e30, best_step1_no_offsets = 0;
  for (long long r = 0; r < *repeats; ++r) {
    auto plain = fit_neutral(*model, *target, no_offsets, nullptr, &*model_system);
    if (!plain) return report_failure(plain.error());
    if (plain->times.total_ms() < best_no_offsets) {
      best_no_offsets = plain->times.total_ms();
      best_step1_no_offsets = plain->times.initial_ms;
    }
    auto fit = fit_neutral(*model, *target, {}, nullptr, &*model_system);
    if (!fit) return report_failure(fit.error());
    if (fit->times.total_ms() < best_neutral) {
      best_neutral = fit->times.total_ms();
      best_step1 = fit->times.initial_ms;
      best_refine = fit->times.refine_ms;
    }
    neutral = std::move(*fit);
  }
  out["neutral_fit_ms"] = best_neutral;
  out["neutral_step1_ms"] = best_step1;
  out["neutral_refine_ms"] = best_refine;
  out["neutral_fit_ms_without_offsets"] = best_no_offsets;
  out["neutral_step1_ms_without_offsets"] = best_step1_no_offsets;
  out["neutral_fit_offsets_ratio"] = best_neutral / best_no_offsets;
  std::vector<float> g0(static_cast<std::size_t>(model->vertex_count) * 3);
  model->evaluate({}, {}, g0);
  const auto tf0 = Clock::now();
  auto transfer = ExpressionTransfer::create(*model, neutral.vertices, g0);
  if (!transfer) return report_failure(transfer.error());
  const double subject_setup_ms = ms_since(tf0);
  out["transfer_factorization_ms"] = subject_setup_ms;
  out["refine_factorization_ms"] = transfer->refine_system().factorization_ms();
  Samples expr, dt;
  const int n_expr = static_cast<int>(std::min<long long>(guide->expressions.size(), 4));
  for (int e = 1; e < n_expr; ++e) {
    auto w = guide_weights(guide->expressions[static_cast<std::size_t>(e)], *model);
    auto gi = guide_mesh(guide->expressions[static_cast<std::size_t>(e)], *model);
    auto parts = guide_part_meshes(guide->expressions[static_cast<std::size_t>(e)], *model);
    if (!gi || !parts) return report_failure(gi ? parts.error() : gi.error());
    auto cap = capture(*model, identity, *w, 100 + e, 30, false);
    if (!cap) return report_failure(cap.error());
    auto t = make_fit_target(*cap, cap->truth_color_px, false);
    if (!t) return report_failure(t.error());
    double best = 1e30;
    for (long long r = 0; r < *repeats; ++r) {
      const auto t1 = Clock::now();
      auto s = transfer->transfer(*gi);
      dt.add(ms_since(t1));
      auto fit = fit_expression(*model, *transfer, *gi, *t, {}, std::nullopt, *parts);
      if (!fit) return report_failure(fit.error());
      best = std::min(best, fit->times.total_ms());
    }
    expr.add(best);
  }
  out["expression_fit_ms"] = expr.mean();
  // The subject's two factorizations happen once for its 19 expressions.
  out["expression_fit_ms_with_setup_share"] = expr.mean() + subject_setup_ms / 19.0;
  out["deformation_transfer_ms"] = dt.mean();
  out["definition"] =
      "wall clock on one thread, best of --repeats; neutral = PCA fit + refinement with the "
      "model's refinement matrix (model_refine_factorization_ms, once per model), and the same "
      "without the offsets along the normal (neutral_fit_ms_without_offsets; "
      "neutral_fit_offsets_ratio = with / without); expression = "
      "transfer + rigid alignment + refinement with the subject's "
      "shared refinement matrix; transfer_factorization_ms = ExpressionTransfer::create, once "
      "per subject: the transfer's and the refinement's factorization (refine_factorization_ms) "
      "of the fitted neutral; expression_fit_ms_with_setup_share adds 1/19 of it; landmark_ms = "
      "tracked frames (detector on the face window + shape predictor)";
  out["targets"] = {{"landmark_ms", 5}, {"neutral_fit_ms", 300}, {"expression_fit_ms", 150}};
  std::cout << out.dump(2) << std::endl;
  return kExitOk;
}

}  // namespace fb::cli::fit_eval
