// facebooth-lab eval fit | bench fit, in parts: fit_commands.cpp (the option tables and eval fit
// over scenarios), fit_eval.cpp (one run over the subjects, capture by capture),
// fit_eval_summary.cpp (its JSON), fit_error_map.cpp (the PNGs) and fit_bench.cpp (bench fit).
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "algo/facemodel/landmark_embedding.hpp"
#include "algo/fitting/face_fit.hpp"
#include "algo/guide/guide_expressions.hpp"
#include "algo/landmarks/landmark_detector.hpp"
#include "host/cli/commands.hpp"
#include "host/cli/stats.hpp"
#include "sim/scoring/fit_metrics.hpp"
#include "sim/subject/synthetic_capture.hpp"
#include "sim/subject/unit_calibration.hpp"

namespace fb::cli::fit_eval {

// The iBUG 68 points' groups (first and last index) the figures are split by.
struct LandmarkGroup {
  const char* name;
  int first, last;
};
inline constexpr std::array<LandmarkGroup, 5> kLandmarkGroups{
    {{"contour", 0, 16}, {"brows", 17, 26}, {"nose", 27, 35}, {"eyes", 36, 47}, {"mouth", 48, 67}}};

inline constexpr const char* kShapePredictorDefault =
    "/usr/share/dlib/shape_predictor_68_face_landmarks.dat";

// fit_commands.cpp: the shape predictor, the plain .dat or a .dat.bz2 decompressed once into a
// cache directory.
Result<LandmarkDetector> load_detector(const std::string& option);

// One run of eval fit over the subjects, in the world `world` (a world_presets.hpp part, or
// empty for the plain synthetic camera).
struct FitEvalSetup {
  const FaceModel* model = nullptr;
  const GuideSet* guide = nullptr;
  const RefineSystem* model_system = nullptr;
  LandmarkDetector* detector = nullptr;  // dlib (scored, and the fit's landmarks with dlib_fit)
  std::vector<int> expressions;
  long long identities = 1, first_seed = 1, frames = 45;
  double noise = 1, robust_noise = 5;
  bool noiseless_depth = false;
  bool skin_map = true;     // FitTarget::skin from frame 0's colour (--skin-map)
  bool scale_parts = true;  // ExpressionFitOptions::scale_parts (--scale-parts)
  bool offsets = true;      // NeutralFitOptions::offset_amplitude_mm as is, or 0 (--offsets)
  ExpressionStart expression_start = ExpressionStart::kModelShapes;  // --expression-start
  bool dlib_fit = false;  // fit dlib's points on frame 0's colour image instead of truth + noise
  // The mesh vertices dlib's points mark (with dlib_fit); unset = the model's landmark vertices.
  std::optional<LandmarkEmbedding> embedding;
  UnitCalibration unit_calibration = UnitCalibration::kSelfCalibrated;
};

// What one run gathers over its captures for the summary.
struct FitTally {
  int captures = 0, captures_failed = 0;
  std::map<std::string, int> failure_reasons;
  Samples rms_init, rms_ref, ne_init, ne_ref, ne_noise, ee_init, ee_ref, erms_ref, lm_err,
      lm_err_interior, neutral_ms, expr_ms, lm_ms_track, lm_ms_full, lift_err;
  int detections = 0, detection_attempts = 0, fit_dlib_found = 0, fit_dlib_attempts = 0;
  Samples fit_dlib_err;
  // dlib's error per landmark over the captures: the mean vector (bias: a convention the model's
  // landmark vertices do not share) and the mean length (bias + scatter).
  std::array<Eigen::Vector2d, 68> dlib_bias_sum;
  std::array<double, 68> dlib_len_sum{};
  nlohmann::json per_subject = nlohmann::json::array();
  std::map<int, Samples> expr_err;
  std::vector<std::uint32_t> eye_mouth;  // the region of the eye_mouth_err figures
  std::vector<double> eye_mouth_err;
  int qa_passed = 0;
  int frames_fused = 0, frames_dropped = 0, boxes_detected = 0;

  FitTally() { dlib_bias_sum.fill(Eigen::Vector2d::Zero()); }
};

// fit_eval.cpp: one run over the subjects; the summary with per_subject.
Result<nlohmann::json> eval_fit_once(const ParsedOptions& options, const FitEvalSetup& setup,
                                     const std::string& world);

// fit_eval_summary.cpp: the figures of one run (eval_fit_once's JSON).
nlohmann::json fit_summary_json(const ParsedOptions& options, const FitEvalSetup& setup,
                                const std::string& world, const FitTally& tally);
nlohmann::json vertex_error_json(const VertexErrorParts& p);

// fit_error_map.cpp: with --png, the error map of the first neutral fit (initial | refined) and,
// beside it, the depth confidence the fit weighted its depth term with.
Result<void> write_fit_pngs(const ParsedOptions& options, const FaceModel& model,
                            const FitResult& neutral, const Capture& cap);

// fit_bench.cpp: facebooth-lab bench fit.
int run_bench_fit(const ParsedOptions& options);

}  // namespace fb::cli::fit_eval
