// facebooth-lab eval fit: the JSON of one run over the subjects (fit_eval_parts.hpp), from what
// fit_eval.cpp gathered over its captures.
#include <filesystem>
#include <numeric>
#include <utility>

#include "sim/lab/fit_eval_parts.hpp"

namespace fb::cli::fit_eval {
namespace {

// dlib's error by landmark group (iBUG 68): the mean error length and the length of the mean
// error vector (what all captures share: a convention, not noise), px, averaged over the group.
nlohmann::json landmark_group_errors(const std::array<Eigen::Vector2d, 68>& bias_sum,
                                     const std::array<double, 68>& len_sum, int n) {
  if (n == 0) return nullptr;
  nlohmann::json out = nlohmann::json::object();
  for (const auto& [name, first, last] : kLandmarkGroups) {
    double len = 0, bias = 0;
    for (int l = first; l <= last; ++l) {
      len += len_sum[static_cast<std::size_t>(l)] / n;
      bias += (bias_sum[static_cast<std::size_t>(l)] / n).norm();
    }
    const int count = last - first + 1;
    out[name] = {{"error_px", len / count}, {"bias_px", bias / count}};
  }
  return out;
}

// The captures, fusion and the fit's landmarks: what the fits were given.
void add_input_figures(const FitEvalSetup& setup, const std::string& world, const FitTally& t,
                       nlohmann::json& out) {
  out["identities"] = setup.identities;
  out["world"] = world.empty() ? "plain synthetic camera" : world;
  out["captures"] = t.captures;
  out["captures_failed"] = t.captures_failed;
  out["capture_failures_by_stage"] = t.failure_reasons;
  // Fusion: frames fused and frames it could not follow (dropped, not fused) over the captures
  // that got that far; the face box from dlib on frame 0 or the fixed rectangle.
  out["fused_frames"] = t.frames_fused;
  out["dropped_frames"] = t.frames_dropped;
  out["face_boxes_detected"] = t.boxes_detected;
  out["fit_landmark_source"] =
      setup.dlib_fit ? "dlib on the colour image of frame 0 (what runs on real frames)"
                     : "ground-truth colour-image landmarks + Gaussian noise";
  if (setup.dlib_fit) {
    out["fit_landmark_error_px"] =
        t.fit_dlib_err.empty() ? nlohmann::json(nullptr) : nlohmann::json(t.fit_dlib_err.mean());
    out["fit_landmark_detections"] =
        std::to_string(t.fit_dlib_found) + "/" + std::to_string(t.fit_dlib_attempts);
    out["fit_landmark_error_by_group"] =
        landmark_group_errors(t.dlib_bias_sum, t.dlib_len_sum, t.fit_dlib_found);
  }
  out["expressions"] = setup.expressions.size();
  out["frames_per_capture"] = setup.frames;
  out["landmark_source"] =
      setup.dlib_fit
          ? "dlib's points on the colour image of frame 0, lifted into the depth camera through "
            "the registration the camera reports and the fused depth"
          : "ground-truth colour-image landmarks (projected model landmark vertices) + Gaussian "
            "noise of landmark_noise_px per axis, lifted into the depth camera through the "
            "registration and the fused depth; dlib is scored separately (landmark_error_px)";
  out["landmark_noise_px"] = setup.noise;
  out["lifted_landmark_error_px"] = t.lift_err.mean();
  out["depth_used"] =
      setup.noiseless_depth ? "noiseless rendering (diagnostic, not the figure)" : "fused";
  out["depth_source"] =
      "KinectFusion (algo/fusion) over the synthetic head-turn take, ray-cast at frame 0";
}

// The neutral and expression fits against the truth, and the device's QA rule.
void add_fit_figures(const FitEvalSetup& setup, const FitTally& t, nlohmann::json& out) {
  out["vertex_error_region"] =
      "the model's fitting vertices (7801 face vertices), camera frame, vs ground truth";
  out["rms_definition"] =
      "point-to-plane distance of fitting vertices to the fused depth (10 mm gate)";
  out["neutral_rms_to_depth_mm_initial"] = t.rms_init.mean();
  out["neutral_rms_to_depth_mm"] = t.rms_ref.mean();
  out["neutral_rms_to_depth_mm_worst"] = t.rms_ref.max();
  out["neutral_vertex_error_mm_initial"] = t.ne_init.mean();
  out["neutral_vertex_error_mm"] = t.ne_ref.mean();
  out["neutral_vertex_error_mm_worst"] = t.ne_ref.max();
  if (!t.ne_noise.empty()) {
    out["robustness_noise_px"] = setup.robust_noise;
    out["neutral_vertex_error_mm_with_robustness_noise"] = t.ne_noise.mean();
  }
  if (!t.ee_ref.empty()) {
    nlohmann::json per_expression = nlohmann::json::object();
    for (const auto& [e, st] : t.expr_err)
      per_expression[setup.guide->expressions[static_cast<std::size_t>(e)].name] = st.mean();
    out["expression_vertex_error_mm_initial"] = t.ee_init.mean();
    out["expression_vertex_error_mm"] = t.ee_ref.mean();
    out["expression_vertex_error_mm_worst"] = t.ee_ref.max();
    out["expression_rms_to_depth_mm"] = t.erms_ref.mean();
    out["expression_vertex_error_mm_by_expression"] = per_expression;
    out["expression_fit_ms_mean"] = t.expr_ms.mean();
  }
  out["neutral_fit_ms_mean"] = t.neutral_ms.mean();
  // Over every fitted capture, neutral and expressions: the tail shows a mesh pulled into
  // holes or depth jumps at the eyes and mouth, which the mean hides.
  out["eye_mouth_vertex_error_mm_p99"] = t.eye_mouth_err.empty()
                                             ? nlohmann::json(nullptr)
                                             : nlohmann::json(percentile(t.eye_mouth_err, 0.99));
  out["eye_mouth_vertex_error_mm_mean"] =
      t.eye_mouth_err.empty()
          ? nlohmann::json(nullptr)
          : nlohmann::json(std::accumulate(t.eye_mouth_err.begin(), t.eye_mouth_err.end(), 0.0) /
                           static_cast<double>(t.eye_mouth_err.size()));
  out["eye_mouth_region"] = "fitting vertices within 10 mm of an eye or mouth landmark vertex (" +
                            std::to_string(t.eye_mouth.size()) + " vertices)";
  // The device's QA rule (algo/fitting/fit_qa.hpp defaults); a capture that failed before its
  // fit fails QA too.
  out["qa_passed"] = std::to_string(t.qa_passed) + "/" + std::to_string(t.captures);
  out["qa_passed_fraction"] = t.captures > 0
                                  ? nlohmann::json(static_cast<double>(t.qa_passed) / t.captures)
                                  : nlohmann::json(nullptr);
}

// dlib scored on the neutral renders (eval_fit_once's score_dlib_on_render).
void add_dlib_figures(const FitEvalSetup& setup, const FitTally& t, nlohmann::json& out) {
  if (!setup.detector) {
    out["landmark_error_px"] = nullptr;
    return;
  }
  out["landmark_error_px"] = t.lm_err.mean();
  out["landmark_error_px_interior"] = t.lm_err_interior.mean();
  out["landmark_detections"] =
      std::to_string(t.detections) + "/" + std::to_string(t.detection_attempts);
  out["landmark_error_note"] =
      "dlib HOG + shape_predictor_68 on the synthetic colour render (frame 0 of each neutral "
      "take; textured only in a world with texture) vs the projected model landmark vertices; "
      "dlib's annotation convention differs from the model's landmark vertices";
  out["landmark_ms_full_image"] = t.lm_ms_full.mean();
  out["landmark_ms_tracked"] = t.lm_ms_track.mean();
}

}  // namespace

nlohmann::json vertex_error_json(const VertexErrorParts& p) {
  return {{"mean_offset_mm", {p.mean_offset_mm.x(), p.mean_offset_mm.y(), p.mean_offset_mm.z()}},
          {"after_translation_mm", p.after_translation_mm},
          {"after_rigid_mm", p.after_rigid_mm},
          {"rigid_rotation_deg", p.rigid_rotation_deg},
          {"normal_mm", p.normal_mm},
          {"tangential_mm", p.tangential_mm},
          {"after_similarity_mm", p.after_similarity_mm},
          {"truth_over_fit_scale", p.similarity_scale}};
}

nlohmann::json fit_summary_json(const ParsedOptions& options, const FitEvalSetup& setup,
                                const std::string& world, const FitTally& tally) {
  nlohmann::json out;
  add_input_figures(setup, world, tally, out);
  add_fit_figures(setup, tally, out);
  add_dlib_figures(setup, tally, out);
  if (!options.get("png").empty())
    out["error_map_png"] = std::filesystem::absolute(options.get("png")).string();
  nlohmann::json targets = {{"neutral_rms_to_depth_mm", 0.3},
                            {"neutral_vertex_error_mm", 1.0},
                            {"expression_vertex_error_mm", 1.5}};
  out["targets"] = targets;
  out["meets_targets"] = tally.rms_ref.mean() <= 0.3 && tally.ne_ref.mean() <= 1.0 &&
                         (tally.ee_ref.empty() || tally.ee_ref.mean() <= 1.5);
  out["per_subject"] = tally.per_subject;
  return out;
}

}  // namespace fb::cli::fit_eval
