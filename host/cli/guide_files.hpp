// The guide recipes as the rig and the lab read them, and the identity of a seeded synthetic
// subject (`rig --synthetic SEED` and facebooth-lab's eval commands draw the same one).
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "algo/core/result.hpp"
#include "algo/facemodel/face_model.hpp"
#include "algo/guide/guide_expressions.hpp"

namespace fb::cli {

Result<std::string> read_text(const std::filesystem::path& path);

// The guide recipes: `option` or DATA_DIR/guide_expressions.json, validated against the model.
Result<GuideSet> load_guide(const FaceModel& model, const std::string& option);

// The identity of synthetic subject `seed` (N(0, 1) per mode), as eval fit draws it.
std::vector<float> identity_draw(std::uint64_t seed, int count);

}  // namespace fb::cli
