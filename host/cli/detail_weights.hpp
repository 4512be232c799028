// Per-frame wrinkle map weights (seed 004 section 4, issue 40 item 5): a session's stored
// detail maps (`facebooth wrinkles`) blended by a tracked frame's blendshape weights. The maps
// are per captured expression, so a frame's detail is E = N + sum_e c_e (D_e - N) with
// c = P^T a (algo/wrinkles/detail_blend.hpp): the c_e, one per capture with detail, are what
// `track --detail-weights` streams to a file and `export --take` writes beside the take, with
// the maps they weigh.
#pragma once

#include <filesystem>
#include <fstream>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "algo/core/result.hpp"
#include "algo/facemodel/face_model.hpp"
#include "algo/guide/guide_expressions.hpp"
#include "algo/wrinkles/detail_blend.hpp"
#include "storage/export/export_folder.hpp"
#include "storage/session_store.hpp"

namespace fb::cli {

struct SessionDetailBlend {
  DetailBlend blend;  // over the face model's fitting shapes
  int neutral_capture = 0;
  std::vector<int> captures;             // layer e -> capture index
  std::vector<std::string> expressions;  // layer e -> the capture's expression
  std::vector<WrinkleDetailData> maps;   // the neutral's, then layer e's (as stored)
  std::vector<std::string> skipped;      // captures with detail left out, and why
};

// The captures of `session` whose wrinkle detail is a layer of the blend, in capture order:
// every capture beside the neutral (capture 0) with detail whose expression is a guide recipe
// (the others go to `skipped`, with why). Empty when the neutral has no detail (nothing to
// blend). What load_session_detail_blend blends and `facebooth sync` sends with the rig.
Result<std::vector<RigDetailCapture>> session_detail_captures(
    const SessionStore& store, SessionId session, const GuideSet& guide,
    std::vector<std::string>* skipped = nullptr);

// The newest detail of each capture of `session`: the neutral's (capture 0) is N, every other
// capture whose expression is a guide recipe is a layer. Fails with what to do when the session
// has no detail (`facebooth wrinkles`) or none beyond the neutral.
Result<SessionDetailBlend> load_session_detail_blend(const SessionStore& store, SessionId session,
                                                     const FaceModel& model, const GuideSet& guide);

// A CSV of per-frame map weights: `frame,time_s,face_found,<expression>@<capture>...`, one row
// per frame, weights with 6 decimals.
class DetailWeightsCsv {
 public:
  static Result<DetailWeightsCsv> open(const std::filesystem::path& path,
                                       const SessionDetailBlend& blend);
  static std::string header(const SessionDetailBlend& blend);
  static std::string row(long long frame, double time_s, bool face_found,
                         std::span<const float> weights);
  Result<void> append(long long frame, double time_s, bool face_found,
                      std::span<const float> weights);
  Result<void> close();

 private:
  std::filesystem::path path_;
  std::ofstream out_;
};

// Layer e's column name, EXPRESSION@CAPTURE, for every layer.
std::vector<std::string> detail_weight_columns(const SessionDetailBlend& blend);

// A stored take's map weights: per frame, c = P^T a from its ARKit curves taken back to the
// model's shapes (ArkitMapping::to_model); frames x layers.
Result<std::vector<float>> take_map_weights(const TakeData& take, const SessionDetailBlend& blend,
                                            const FaceModel& model);

// What the map weights mean, for manifests and reports.
std::string detail_weights_description();

// For `export --take`: beside the take's CSV, take_ID_detail_weights.csv (the take's weights
// through the blend; ARKit curves back to the model's shapes) and the maps the weights drive
// (wrinkles/capture_I_normal.png, wrinkles/capture_I_displacement.pgm). Returns the layers.
Result<int> write_take_detail_weights(ExportFolder& folder, const TakeData& take,
                                      const SessionDetailBlend& blend, const FaceModel& model);

}  // namespace fb::cli
