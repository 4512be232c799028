// `rig --refit` (issue 38, item 3): a stored session's captures fitted again on the host from
// what the store keeps of each capture (the fused depth, the landmarks in colour pixels, the
// unit's calibration), the neutral first and every expression from that neutral, with the
// host's full settings (full_fit_options()). The new meshes are added in one transaction (all
// or none; the booth's fits stay, superseded because the newest mesh of a capture is the one
// used), so `rig` then rigs from them.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "algo/core/result.hpp"
#include "algo/facemodel/face_model.hpp"
#include "algo/facemodel/landmark_embedding.hpp"
#include "algo/fitting/face_fit.hpp"
#include "algo/guide/guide_expressions.hpp"
#include "storage/session_store.hpp"

namespace fb::cli {

struct RefitOptions {
  NeutralFitOptions neutral;
  ExpressionFitOptions expression;
  std::function<void(int done, int total)> progress;  // after each capture
  // The mesh vertices the stored (dlib) landmarks mark; unset = the model's landmark vertices.
  std::optional<LandmarkEmbedding> embedding;
};

// The host's settings (docs/sync.md "rig --refit" has the figures that chose them).
RefitOptions full_fit_options();

struct RefitCapture {
  int index = 0;
  std::string expression;
  MeshId previous_mesh = 0;  // the fit it supersedes (0: the capture had none)
  MeshId mesh = 0;           // the refit
  double rms_to_depth_mm = 0;
  double landmark_error_mm = 0;
  double fit_ms = 0;
};

struct RefitReport {
  std::vector<RefitCapture> captures;
  std::vector<std::string> skipped;  // "smile (capture 2): why"
  std::string calibration_note;      // set when the session recorded no calibration
  double seconds = 0;
};

// Refits every done capture of `session` that has landmarks and fused depth and stores the new
// meshes (the store must be writable). Fails when the neutral (capture 0) cannot be refit: the
// expressions are fitted from it.
Result<RefitReport> refit_session(SessionStore& store, SessionId session, const FaceModel& model,
                                  const GuideSet& guide, const RefitOptions& options);

}  // namespace fb::cli
