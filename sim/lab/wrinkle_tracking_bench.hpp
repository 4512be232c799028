// `bench wrinkles`' tracking part (seed 004 section 4, issue 40's tracking_overhead_ms): the
// per-frame cost of a tracked frame's blended detail, DetailBlend (support texels only, in
// capture space) against the same blend over every texel of the full-resolution maps.
#pragma once

#include <nlohmann/json.hpp>

#include "algo/core/result.hpp"
#include "algo/facemodel/face_model.hpp"
#include "algo/guide/guide_expressions.hpp"
#include "algo/wrinkles/wrinkle_detail.hpp"
#include "sim/lab/wrinkle_case.hpp"

namespace fb::cli {

// `detail`: the case's synthesised heights; `map_height`: the maps' height (width x tiles).
Result<nlohmann::json> bench_detail_blend(const FaceModel& model, const GuideSet& guide,
                                          const WrinkleCase& c, const WrinkleDetail& detail,
                                          int map_height, int frames);

}  // namespace fb::cli
