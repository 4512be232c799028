// glTF 2.0 binary (.glb) of a blendshape rig, built for engines and DCC tools to take as is:
//  - the neutral mesh with per-vertex NORMALs (area-weighted) and, when the rig has the face
//    model's topology, the model's UV layout as TEXCOORD_0 (v flipped to glTF's top-left
//    origin). glTF has one index per vertex, so a vertex with several UVs (a seam) becomes one
//    vertex per UV; its copies share position, normal and every target's deltas;
//  - one morph target per blendshape with POSITION and NORMAL deltas (the target's own vertex
//    normals minus the neutral's), names in mesh.extras.targetNames (the convention Blender,
//    three.js and Babylon read), default weights zero;
//  - one PBR metallic-roughness material (a skin tone, metallic 0, roughness 0.6), or with a
//    base colour texture when one is given.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "algo/core/result.hpp"
#include "storage/export/mesh_geometry.hpp"
#include "storage/stored_data.hpp"

namespace fb {

struct GlbOptions {
  std::string name = "face";
  float scale = 0.001f;          // facebooth meshes are in millimetres; glTF's unit is the metre
  const MeshUvs* uvs = nullptr;  // the UV layout; ignored unless it fits the rig's triangles
  std::array<float, 4> base_color = {0.80f, 0.60f, 0.50f, 1.0f};  // linear RGBA
  // A PNG in the UV layout as the material's baseColorTexture (embedded; used with the UVs
  // only). The subject's own texture (issue 37 item 3) is not built yet; this is where it goes.
  const std::vector<std::uint8_t>* base_color_png = nullptr;
  float roughness = 0.6f;
};

Result<std::vector<std::uint8_t>> encode_glb(const RigData& rig, const GlbOptions& options = {});

}  // namespace fb
