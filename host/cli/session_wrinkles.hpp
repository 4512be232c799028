// The wrinkle detail of a stored session (issue 40, `facebooth wrinkles`): each capture with a
// fitted mesh (the neutral first) through algo/wrinkles' capture_detail(), its maps stored with
// the session and the rig serving it (SessionStore::add_wrinkle_detail).
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "algo/core/result.hpp"
#include "algo/facemodel/face_model.hpp"
#include "algo/wrinkles/capture_detail.hpp"
#include "storage/session_store.hpp"

namespace fb::cli {

struct CaptureWrinkleReport {
  int capture_index = 0;
  std::string expression;
  int regions = 0;                // regions synthesised in (detected and/or given)
  int given_regions = 0;          // of them given by hand
  int texels_with_detail = 0;     // of the maps
  double max_height_mm = 0.0;     // largest |displacement| in the maps
  bool ratio_to_neutral = false;  // synthesised from the expression ratio image
  std::optional<WrinkleDetailId> stored;
  double seconds = 0.0;
};

struct WrinkleSessionOptions {
  int size = 256;  // map height; width = size x the layout's tiles
  bool save = true;
  std::vector<WrinkleExemplar> exemplars;
  double exemplar_mm_per_px = 0.25;
  // Hand-given regions in the colour frame's pixels (--region), for one capture or (no index)
  // every capture; they replace the detected regions unless `also_detect`.
  struct GivenRegion {
    std::optional<int> capture;
    PixelRect rect;
  };
  std::vector<GivenRegion> regions;
  bool also_detect = false;
  bool zones = true;         // detect only in the wrinkle zones (SalientOptions::wrinkle_zones)
  bool local_light = false;  // WrinkleDetailOptions::local_light
};

// Fails with what to do when the session has no rig, no fitted neutral, or a capture without a
// colour frame or landmarks. `progress(done, total)` after each capture.
Result<std::vector<CaptureWrinkleReport>> wrinkle_session(
    SessionStore& store, SessionId session, const FaceModel& model,
    const WrinkleSessionOptions& options, const std::function<void(int, int)>& progress = {});

}  // namespace fb::cli
