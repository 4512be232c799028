// The kiosk's guide sequence: the 20 FaceWarehouse expressions from data/guide_expressions.json
// (owned by algo/guide), read here only for what the daemon needs: names, labels, and the
// weight recipe as a synthetic-camera expression spec (so the simulated subject imitates it).
#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "algo/core/result.hpp"

namespace fb {

struct GuideStep {
  std::string name;            // machine name, e.g. "mouth_stretch"
  std::string label;           // kiosk text
  std::string synthetic_expr;  // "jawOpen:0.7+mouthStretch_L:0.4", or "neutral"
  std::vector<std::pair<std::string, float>> weights;  // the recipe (model expression names)
};

Result<std::vector<GuideStep>> parse_guide_steps(std::string_view json_text);
Result<std::vector<GuideStep>> load_guide_steps(const std::filesystem::path& path);

}  // namespace fb
