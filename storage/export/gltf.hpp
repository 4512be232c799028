// glTF 2.0 binary (.glb) of a blendshape rig: the neutral mesh with one morph target (POSITION
// deltas) per blendshape, target names in mesh.extras.targetNames (the convention Blender,
// three.js and Babylon read), default weights zero.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "algo/core/result.hpp"
#include "storage/stored_data.hpp"

namespace fb {

struct GlbOptions {
  std::string name = "face";
  float scale = 0.001f;  // facebooth meshes are in millimetres; glTF's unit is the metre
};

Result<std::vector<std::uint8_t>> encode_glb(const RigData& rig, const GlbOptions& options = {});

}  // namespace fb
