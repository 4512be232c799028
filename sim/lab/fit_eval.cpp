// facebooth-lab eval fit, one run over the subjects (fit_eval_parts.hpp): per subject and
// expression, a synthetic head-turn take (random identity, the guide recipe's weights, sensor
// noise on) -> KinectFusion -> ray-cast frontal depth + normals -> landmarks (ground-truth colour
// points + Gaussian pixel noise, or dlib, lifted with the registration and the fused depth) ->
// neutral fit / deformation transfer + refinement, each scored against the truth.
#include <cmath>
#include <cstdio>
#include <iostream>
#include <optional>
#include <random>

#include "algo/core/clock.hpp"
#include "algo/core/figure_text.hpp"
#include "algo/fitting/expression_transfer.hpp"
#include "algo/fitting/fit_qa.hpp"
#include "host/cli/guide_files.hpp"
#include "sim/lab/fit_eval_parts.hpp"
#include "sim/subject/personal_expressions.hpp"

namespace fb::cli::fit_eval {
namespace {

// How far a subject of the identity part makes each expression its own way
// (personal_expressions.hpp): amounts 0.7-1.3 of the model's, +-30 % over the face.
constexpr double kPersonalExpressionSpread = 0.3;

// After a capture: go on with the subject's next one, or stop the subject (no neutral fit).
enum class Next { kCapture, kSubject };

// One eval_fit_once run: its inputs and what it gathers.
struct FitRun {
  const ParsedOptions& options;
  const FitEvalSetup& setup;
  const std::string& world;
  // In a world (scenario runs) a capture that fails (fusion loses the face, dlib finds none, a
  // fit fails) is a figure, not an abort: it is counted and its reason kept.
  bool lenient = false;
  FitTally tally;
};

// One subject: its identity, its landmark noise and, once fitted, its neutral (the expressions'
// transfer starts from it).
struct FitSubject {
  long long index = 0;
  std::uint64_t seed = 0;
  std::vector<float> identity;
  std::mt19937_64 rng;
  FitResult neutral;
  std::vector<float> g0;
  std::optional<ExpressionTransfer> transfer;
  // The subject's own expression shapes in a world with the identity part (else empty: the
  // model's).
  std::vector<float> personal_basis;
};

// Why a capture gave no figure: an error outside a world, a counted failure in one (the reason in
// `j`). Without the neutral (e == 0) the subject's expressions cannot be fitted.
Result<Next> capture_failed(FitRun& run, int e, const std::string& name, const std::string& stage,
                            const Error& error, nlohmann::json& j) {
  if (!run.lenient) return fail(error);
  ++run.tally.captures_failed;
  ++run.tally.failure_reasons[stage];
  j["failed"] = stage + ": " + error.message;
  std::cerr << "  " << name << " failed at " << stage << ": " << error.message << "\n";
  return e == 0 ? Next::kSubject : Next::kCapture;
}

// The fit's landmarks: the true colour-image points + noise, or (dlib_fit) what runs on real
// frames: dlib on the colour image of frame 0, scored against the truth.
Result<std::vector<Eigen::Vector2d>> fit_landmark_points(FitRun& run, const Capture& cap,
                                                         std::mt19937_64& rng, nlohmann::json& j) {
  std::vector<Eigen::Vector2d> fit_points = noisy(cap.truth_color_px, run.setup.noise, rng);
  if (!run.setup.dlib_fit) return fit_points;
  FitTally& t = run.tally;
  ++t.fit_dlib_attempts;
  run.setup.detector->reset_tracking();
  auto found = run.setup.detector->detect(cap.color);
  if (!found) return found.failure();
  ++t.fit_dlib_found;
  fit_points.assign(found->points.begin(), found->points.end());
  double sum = 0;
  for (int l = 0; l < 68; ++l) {
    const Eigen::Vector2d d =
        fit_points[static_cast<std::size_t>(l)] - cap.truth_color_px[static_cast<std::size_t>(l)];
    sum += d.norm();
    t.dlib_bias_sum[static_cast<std::size_t>(l)] += d;
    t.dlib_len_sum[static_cast<std::size_t>(l)] += d.norm();
  }
  t.fit_dlib_err.add(sum / 68);
  j["fit_landmark_error_px"] = sum / 68;
  return fit_points;
}

// Fusion's figures (frames, face box) and how well the colour -> depth lifting puts the points
// (vs the true depth-image points).
void score_fused_capture(FitRun& run, const Capture& cap, const FitTarget& target,
                         nlohmann::json& j) {
  FitTally& t = run.tally;
  j["fused_frames"] = cap.fused_frames;
  j["dropped_frames"] = cap.dropped_frames;
  j["face_box"] = {{"source", cap.box_source},
                   {"x", cap.box.rect.x0},
                   {"y", cap.box.rect.y0},
                   {"width", cap.box.rect.width()},
                   {"height", cap.box.rect.height()}};
  if (!cap.box_note.empty()) j["face_box"]["note"] = cap.box_note;
  t.frames_fused += cap.fused_frames;
  t.frames_dropped += cap.dropped_frames;
  t.boxes_detected += cap.box_source == "dlib";
  double sum = 0;
  int n = 0;
  for (int l = 0; l < 68; ++l)
    if (target.landmarks[static_cast<std::size_t>(l)].valid) {
      sum += (target.landmarks[static_cast<std::size_t>(l)].pixel -
              cap.truth_depth_px[static_cast<std::size_t>(l)])
                 .norm();
      ++n;
    }
  j["lifted_landmark_error_px"] = n ? sum / n : NAN;
  t.lift_err.add(n ? sum / n : NAN);
}

// The device's QA on this fit and the eye/mouth region's error, per capture: which capture
// fails and where the region's tail comes from.
void score_qa_and_region(FitRun& run, const FitResult& fit, const FitTarget& target,
                         const Capture& cap, nlohmann::json& j) {
  FitTally& t = run.tally;
  const bool qa = fit_passes_qa(fit, target);
  t.qa_passed += qa;
  j["qa_passed"] = qa;
  j["landmark_disagreement_mm"] = landmark_disagreement_mm(fit, target);
  for (const auto& [name, first, last] : kLandmarkGroups) {
    double sum = 0;
    int n = 0;
    for (int l = first; l <= last; ++l)
      if (target.landmarks[static_cast<std::size_t>(l)].valid &&
          std::isfinite(fit.landmark_residual_mm[static_cast<std::size_t>(l)])) {
        sum += fit.landmark_residual_mm[static_cast<std::size_t>(l)];
        ++n;
      }
    if (n > 0) j["landmark_residual_mm_by_group"][name] = sum / n;
  }
  std::vector<double> region;
  append_vertex_distances(fit.vertices, fit.camera_from_model, cap.truth_mesh, cap.truth_pose,
                          t.eye_mouth, region);
  if (!region.empty()) j["eye_mouth_vertex_error_mm_p99"] = percentile(region, 0.99);
  t.eye_mouth_err.insert(t.eye_mouth_err.end(), region.begin(), region.end());
}

// Where a neutral's error is: on skin or under hair and a beard (the skin map's split at the
// true vertex), and how far the fused depth on skin is from the noiseless rendering.
void score_cover(const FitResult& neutral, const FitTarget& target, const Capture& cap,
                 const FaceModel& model, nlohmann::json& j) {
  std::vector<std::uint32_t> skin, covered;
  for (std::uint32_t v : model.fitting_vertices) {
    const std::size_t i = 3 * std::size_t{v};
    const Eigen::Vector3d p =
        cap.truth_pose.apply({cap.truth_mesh[i], cap.truth_mesh[i + 1], cap.truth_mesh[i + 2]});
    const Eigen::Vector2d uv = target.intrinsics.project(p);
    const int px = static_cast<int>(std::lround(uv.x())),
              py = static_cast<int>(std::lround(uv.y()));
    if (!target.skin.contains(px, py)) continue;
    (target.skin.at(px, py) < 0.5f ? covered : skin).push_back(v);
  }
  auto err = [&](const std::vector<std::uint32_t>& set) {
    return set.empty()
               ? nlohmann::json(nullptr)
               : nlohmann::json(mean_vertex_distance(neutral.vertices, neutral.camera_from_model,
                                                     cap.truth_mesh, cap.truth_pose, set));
  };
  double sum = 0, sum_abs = 0;
  int n = 0;
  for (int y = 0; y < target.depth_mm.height; ++y)
    for (int x = 0; x < target.depth_mm.width; ++x) {
      const float f = target.depth_mm.at(x, y), t0 = cap.noiseless.at(x, y);
      if (f > 0 && t0 > 0 && target.skin.at(x, y) >= 0.5f && std::abs(f - t0) < 20) {
        sum += f - t0;
        sum_abs += std::abs(f - t0);
        ++n;
      }
    }
  j["fused_minus_noiseless_on_skin_mm"] = {
      {"mean", n ? sum / n : 0.0}, {"mae", n ? sum_abs / n : 0.0}, {"pixels", n}};
  auto parts = [&](const std::vector<std::uint32_t>& set) {
    return set.empty() ? nlohmann::json(nullptr)
                       : vertex_error_json(vertex_error_parts(
                             neutral.vertices, neutral.camera_from_model, cap.truth_mesh,
                             cap.truth_pose, set, model.triangles));
  };
  j["vertex_error_parts_by_cover"] = {{"skin", parts(skin)}, {"hair_or_beard", parts(covered)}};
  j["vertex_error_by_cover"] = {{"skin_mm", err(skin)},
                                {"skin_vertices", skin.size()},
                                {"hair_or_beard_mm", err(covered)},
                                {"hair_or_beard_vertices", covered.size()}};
}

// The neutral fit against the truth: vertex error (initial and refined), RMS to depth, where
// the error lies.
void score_neutral_fit(FitRun& run, const FitResult& neutral, const FitTarget& target,
                       const Capture& cap, nlohmann::json& j) {
  const FaceModel& model = *run.setup.model;
  FitTally& t = run.tally;
  score_qa_and_region(run, neutral, target, cap, j);
  const double vi = mean_vertex_distance(neutral.initial_vertices, neutral.camera_from_model,
                                         cap.truth_mesh, cap.truth_pose, model.fitting_vertices);
  const double vr = mean_vertex_distance(neutral.vertices, neutral.camera_from_model,
                                         cap.truth_mesh, cap.truth_pose, model.fitting_vertices);
  t.rms_init.add(neutral.rms_to_depth_mm_initial);
  t.rms_ref.add(neutral.rms_to_depth_mm);
  t.ne_init.add(vi);
  t.ne_ref.add(vr);
  t.neutral_ms.add(neutral.times.total_ms());
  j["rms_to_depth_mm_initial"] = neutral.rms_to_depth_mm_initial;
  j["rms_to_depth_mm"] = neutral.rms_to_depth_mm;
  j["vertex_error_mm_initial"] = vi;
  j["vertex_error_mm"] = vr;
  const VertexErrorParts parts =
      vertex_error_parts(neutral.vertices, neutral.camera_from_model, cap.truth_mesh,
                         cap.truth_pose, model.fitting_vertices, model.triangles);
  j["vertex_error_parts"] = vertex_error_json(parts);
  if (!target.skin.empty()) score_cover(neutral, target, cap, model, j);
  std::fprintf(stderr,
               "  neutral: offset %.2f %.2f %.2f mm; error less the offset %.2f mm, less "
               "a rigid motion %.2f mm (%.2f deg); along the normal %.2f, across %.2f mm\n",
               parts.mean_offset_mm.x(), parts.mean_offset_mm.y(), parts.mean_offset_mm.z(),
               parts.after_translation_mm, parts.after_rigid_mm, parts.rigid_rotation_deg,
               parts.normal_mm, parts.tangential_mm);
  j["fit_ms"] = neutral.times.total_ms();
  j["fit_rounds"] = neutral.rounds;
  std::fprintf(stderr, "  neutral: RMS to depth %s -> %s mm, vertex error %s -> %s mm, %.0f ms\n",
               figure_text(neutral.rms_to_depth_mm_initial, 3).c_str(),
               figure_text(neutral.rms_to_depth_mm, 3).c_str(), figure_text(vi, 3).c_str(),
               figure_text(vr, 3).c_str(), neutral.times.total_ms());
}

// The product's neutral fit, or without its offsets along the normal (--offsets off).
NeutralFitOptions neutral_options(const FitEvalSetup& setup) {
  NeutralFitOptions options;
  if (!setup.offsets) options.offset_amplitude_mm = 0;
  return options;
}

// Robustness: the same capture fitted again with stronger landmark noise.
Result<void> robustness_fit(FitRun& run, const Capture& cap, std::mt19937_64& rng,
                            nlohmann::json& j) {
  const FitEvalSetup& setup = run.setup;
  auto t2 = make_fit_target(cap, noisy(cap.truth_color_px, setup.robust_noise, rng),
                            setup.noiseless_depth);
  if (!t2) return t2.failure();
  auto f2 = fit_neutral(*setup.model, *t2, neutral_options(setup), nullptr, &*setup.model_system);
  if (!f2) return f2.failure();
  const double vn = mean_vertex_distance(f2->vertices, f2->camera_from_model, cap.truth_mesh,
                                         cap.truth_pose, setup.model->fitting_vertices);
  run.tally.ne_noise.add(vn);
  j["vertex_error_mm_robustness_noise"] = vn;
  return success();
}

// dlib on the neutral's (untextured outside a texture world) render: its error against the
// truth, and its tracking cost over the take.
void score_dlib_on_render(FitRun& run, const Capture& cap, nlohmann::json& j) {
  LandmarkDetector* detector = run.setup.detector;
  FitTally& t = run.tally;
  ++t.detection_attempts;
  detector->reset_tracking();
  const auto t0 = Clock::now();
  auto found = detector->detect(cap.color);
  t.lm_ms_full.add(ms_since(t0));
  if (!found) return;
  ++t.detections;
  double sum = 0, sum_in = 0;
  for (int i = 0; i < 68; ++i) {
    const double d = (found->points[static_cast<std::size_t>(i)] -
                      cap.truth_color_px[static_cast<std::size_t>(i)])
                         .norm();
    sum += d;
    if (i >= 17) sum_in += d;
  }
  t.lm_err.add(sum / 68);
  t.lm_err_interior.add(sum_in / 51);
  j["dlib_landmark_error_px"] = sum / 68;
  for (std::size_t f = 1; f < cap.colors.size(); ++f) {
    const auto t1 = Clock::now();
    auto tracked = detector->detect(cap.colors[f]);
    if (tracked && tracked->tracked) t.lm_ms_track.add(ms_since(t1));
  }
}

// The neutral capture (e == 0): fitted, scored, and the subject's expression transfer set up.
Result<Next> neutral_capture(FitRun& run, FitSubject& subject, const Capture& cap,
                             const FitTarget& target, nlohmann::json& j) {
  const FitEvalSetup& setup = run.setup;
  const FaceModel& model = *setup.model;
  auto fit = fit_neutral(model, target, neutral_options(setup), nullptr, &*setup.model_system);
  if (!fit) {
    auto stop =
        capture_failed(run, 0, setup.guide->expressions[0].name, "neutral fit", fit.error(), j);
    if (!stop) return stop.failure();
    return Next::kSubject;
  }
  subject.neutral = std::move(*fit);
  const FitResult& neutral = subject.neutral;
  score_neutral_fit(run, neutral, target, cap, j);
  if (setup.robust_noise > 0)
    if (auto ok = robustness_fit(run, cap, subject.rng, j); !ok) return ok.failure();
  subject.g0.resize(static_cast<std::size_t>(model.vertex_count) * 3);
  model.evaluate({}, {}, subject.g0);
  auto tr = ExpressionTransfer::create(model, neutral.vertices, subject.g0);
  if (!tr) return tr.failure();
  subject.transfer.emplace(std::move(*tr));
  if (setup.detector) score_dlib_on_render(run, cap, j);
  if (subject.index == 0)
    if (auto ok = write_fit_pngs(run.options, model, neutral, cap); !ok) return ok.failure();
  return Next::kCapture;
}

// An expression capture (e > 0): the guide's expression transferred onto the subject's neutral,
// fitted and scored.
Result<Next> expression_capture(FitRun& run, FitSubject& subject, int e, const Capture& cap,
                                const FitTarget& target, nlohmann::json& j) {
  const FaceModel& model = *run.setup.model;
  const GuideExpression& ge = run.setup.guide->expressions[static_cast<std::size_t>(e)];
  FitTally& t = run.tally;
  auto gi = guide_mesh(ge, model);
  if (!gi) return gi.failure();
  auto parts = guide_part_meshes(ge, model);
  if (!parts) return parts.failure();
  ExpressionFitOptions fit_options;
  fit_options.scale_parts = run.setup.scale_parts;
  fit_options.start = run.setup.expression_start;
  auto fit =
      fit_expression(model, *subject.transfer, *gi, target, fit_options, std::nullopt, *parts);
  if (!fit) {
    auto stop = capture_failed(run, e, ge.name, "expression fit", fit.error(), j);
    if (!stop) return stop.failure();
    return Next::kCapture;
  }
  score_qa_and_region(run, *fit, target, cap, j);
  const double vi = mean_vertex_distance(fit->initial_vertices, fit->camera_from_model,
                                         cap.truth_mesh, cap.truth_pose, model.fitting_vertices);
  const double vr = mean_vertex_distance(fit->vertices, fit->camera_from_model, cap.truth_mesh,
                                         cap.truth_pose, model.fitting_vertices);
  t.ee_init.add(vi);
  t.ee_ref.add(vr);
  t.erms_ref.add(fit->rms_to_depth_mm);
  t.expr_ms.add(fit->times.total_ms());
  t.expr_err[e].add(vr);
  j["rms_to_depth_mm_initial"] = fit->rms_to_depth_mm_initial;
  j["rms_to_depth_mm"] = fit->rms_to_depth_mm;
  j["vertex_error_mm_initial"] = vi;
  j["vertex_error_mm"] = vr;
  j["fit_ms"] = fit->times.total_ms();
  for (std::size_t k = 0; k < fit->part_amplitudes.size() && k < ge.weights.size(); ++k)
    j["part_amplitudes"][ge.weights[k].first] = fit->part_amplitudes[k];
  std::fprintf(stderr, "  %s: RMS to depth %s -> %s mm, vertex error %s -> %s mm, %.0f ms\n",
               ge.name.c_str(), figure_text(fit->rms_to_depth_mm_initial, 3).c_str(),
               figure_text(fit->rms_to_depth_mm, 3).c_str(), figure_text(vi, 3).c_str(),
               figure_text(vr, 3).c_str(), fit->times.total_ms());
  return Next::kCapture;
}

// One capture of a subject (expression e): capture + landmarks, fit, scoring; figures in `j`.
Result<Next> eval_fit_capture(FitRun& run, FitSubject& subject, int e,
                              const std::vector<float>& weights, nlohmann::json& j) {
  const FitEvalSetup& setup = run.setup;
  const GuideExpression& ge = setup.guide->expressions[static_cast<std::size_t>(e)];
  LandmarkDetector* detector = setup.detector;
  const std::uint64_t seed = subject.seed;
  auto cap =
      capture(*setup.model, subject.identity, weights, seed * 1000 + static_cast<std::uint64_t>(e),
              static_cast<int>(setup.frames), detector && e == 0 && subject.index == 0,
              subject.personal_basis, run.world, seed, setup.unit_calibration, detector);
  if (!cap) return capture_failed(run, e, ge.name, "capture", cap.error(), j);
  auto fit_points = fit_landmark_points(run, *cap, subject.rng, j);
  if (!fit_points) return capture_failed(run, e, ge.name, "dlib", fit_points.error(), j);
  auto target = make_fit_target(*cap, *fit_points, setup.noiseless_depth, setup.skin_map);
  if (target && setup.dlib_fit && setup.embedding)
    target->landmark_vertices = setup.embedding->for_expression(ge.name);
  if (!target) return capture_failed(run, e, ge.name, "landmarks", target.error(), j);
  score_fused_capture(run, *cap, *target, j);
  if (e == 0) return neutral_capture(run, subject, *cap, *target, j);
  return expression_capture(run, subject, e, *cap, *target, j);
}

// One subject (the s-th): the neutral, then its expressions; its per-capture figures.
Result<nlohmann::json> eval_fit_subject(FitRun& run, long long s) {
  const FitEvalSetup& setup = run.setup;
  FitSubject subject;
  subject.index = s;
  subject.seed = static_cast<std::uint64_t>(setup.first_seed + s);
  subject.identity = identity_draw(subject.seed, setup.model->identity_count);
  subject.rng.seed(subject.seed * 7919 + 17);
  if (run.world == "identity" || run.world == "realistic")
    subject.personal_basis =
        personal_expression_basis(*setup.model, subject.seed, kPersonalExpressionSpread);
  nlohmann::json out;
  out["seed"] = subject.seed;
  nlohmann::json exprs = nlohmann::json::array();
  for (int e : setup.expressions) {
    const GuideExpression& ge = setup.guide->expressions[static_cast<std::size_t>(e)];
    auto weights = guide_weights(ge, *setup.model);
    if (!weights) return weights.failure();
    std::cerr << "eval fit: subject " << subject.seed << ", " << ge.name << " ...\n";
    nlohmann::json j;
    j["expression"] = ge.name;
    ++run.tally.captures;
    auto next = eval_fit_capture(run, subject, e, *weights, j);
    if (!next) return next.failure();
    exprs.push_back(j);
    if (*next == Next::kSubject) break;
  }
  out["captures"] = exprs;
  return out;
}

}  // namespace

Result<nlohmann::json> eval_fit_once(const ParsedOptions& options, const FitEvalSetup& setup,
                                     const std::string& world) {
  FitRun run{options, setup, world, !world.empty(), {}};
  run.tally.eye_mouth = eye_mouth_vertices(*setup.model);
  for (long long s = 0; s < setup.identities; ++s) {
    auto subject = eval_fit_subject(run, s);
    if (!subject) return subject.failure();
    run.tally.per_subject.push_back(*subject);
  }
  return fit_summary_json(options, setup, world, run.tally);
}

}  // namespace fb::cli::fit_eval
