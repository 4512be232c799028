// glTF 2.0 binary (.glb) of a blendshape rig, built for engines and DCC tools to take as is:
//  - the neutral mesh with per-vertex NORMALs (area-weighted) and, when the rig has the face
//    model's topology, the model's UV layout as TEXCOORD_0 (v flipped to glTF's top-left
//    origin). glTF has one index per vertex, so a vertex with several UVs (a seam) becomes one
//    vertex per UV; its copies share position, normal and every target's deltas;
//  - one morph target per blendshape with POSITION and NORMAL deltas (the target's own vertex
//    normals minus the neutral's), names in mesh.extras.targetNames (the convention Blender,
//    three.js and Babylon read), default weights zero;
//  - one PBR metallic-roughness material (a skin tone, metallic 0, roughness 0.6), or with a
//    base colour texture when one is given;
//  - with a normal map (the wrinkle detail, issue 40), the material's normalTexture and a
//    TANGENT per vertex: xyz along +u of the UV layout, w chosen so that glTF's bitangent
//    cross(normal, tangent) * w runs along +v of the layout (up in the image), the map's green
//    axis. Given rather than left to a viewer's MikkTSpace, so every viewer agrees;
//  - with an animation (gltf_animation.hpp), the mesh's node under a "head" node and one glTF
//    animation: the targets' weights per frame on the mesh's node, the head pose on its parent.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "algo/core/result.hpp"
#include "storage/export/gltf_animation.hpp"
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
  // A tangent-space normal map (PNG, x along +u, y along +v) in the UV layout as the material's
  // normalTexture (with the UVs only); adds TANGENT.
  const std::vector<std::uint8_t>* normal_png = nullptr;
  // One animation of the morph targets' weights (in the rig's shape order) and the head pose;
  // nullptr: a still rig with one node.
  const GlbAnimation* animation = nullptr;
};

// Per-vertex glTF tangents (4 floats each) of a mesh with one UV per vertex: +u on the surface
// made orthogonal to the vertex normal, w = +-1 so cross(normal, tangent) * w follows +v.
std::vector<float> vertex_tangents(const std::vector<float>& positions,
                                   const std::vector<float>& normals,
                                   const std::vector<float>& texcoords,
                                   const std::vector<std::uint32_t>& triangles);

Result<std::vector<std::uint8_t>> encode_glb(const RigData& rig, const GlbOptions& options = {});

}  // namespace fb
