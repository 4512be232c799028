// A rig with the face model's shape names (eyeBlink_L, browInnerUp_L/_R, ...) turned into
// Apple's 52 ARKit blendshapes in Apple's order, through the mapping the tracker's outputs use
// (algo/tracking/arkit.hpp): sided shapes renamed (eyeBlink_L -> eyeBlinkLeft), split pairs
// combined (browInnerUp = browInnerUp_L + browInnerUp_R deltas, likewise cheekPuff), tongueOut
// a zero shape (the skin has no tongue), shapes ARKit has no name for (cheekRaiser_L/R,
// PupilDilate_L/R) left out.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "algo/core/result.hpp"
#include "storage/stored_data.hpp"

namespace fb {

// Which names exports give the blendshapes: `arkit` (the 52, Apple's order) or `model` (the rig's
// own, as fitted).
enum class ShapeNames { kArkit, kModel };
Result<ShapeNames> parse_shape_names(std::string_view name);
const char* to_string(ShapeNames names);

struct ArkitRig {
  RigData rig;                        // 52 shapes named as kArkitNames, same topology
  std::vector<std::string> dropped;   // the input's shapes without an ARKit name
  std::vector<std::string> combined;  // e.g. "browInnerUp = browInnerUp_L + browInnerUp_R"
};

// Fails (saying to use --names model) when the rig's names do not cover ARKit's curves.
Result<ArkitRig> to_arkit_rig(const RigData& rig);

}  // namespace fb
