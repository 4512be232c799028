// storage/export internal: the animation written into a glTF document being built (gltf.cpp).
#pragma once

#include <nlohmann/json.hpp>

#include "storage/export/glb_buffer.hpp"
#include "storage/export/gltf_animation.hpp"

namespace fb {

struct GlbAnimationNodes {
  int head = 0;  // the parent node: translation and rotation
  int mesh = 1;  // the mesh's node: weights
};

// Appends `animation` (checked by check_animation) to gltf["animations"], its data to `buffer`.
void add_animation(nlohmann::json& gltf, GlbBuffer& buffer, const GlbAnimation& animation,
                   const GlbAnimationNodes& nodes);

}  // namespace fb
