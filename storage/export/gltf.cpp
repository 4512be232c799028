#include "storage/export/gltf.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include "storage/export/glb_buffer.hpp"
#include "storage/export/gltf_animation_json.hpp"

namespace fb {

namespace {

// Per-output-vertex texture coordinates of a seam-split mesh (glTF's v runs downwards).
std::vector<float> split_texcoords(const SplitMesh& split, const std::vector<float>& uvs) {
  std::vector<float> texcoords(2 * split.source_vertex.size());
  for (std::size_t o = 0; o < split.source_vertex.size(); ++o) {
    const std::size_t uv = split.uv_index[o];
    texcoords[2 * o] = uvs[2 * uv];
    texcoords[2 * o + 1] = 1.0f - uvs[2 * uv + 1];
  }
  return texcoords;
}

// One PBR material for the skin; with a texture its colour comes from baseColorTexture 0.
nlohmann::json skin_material(const GlbOptions& options, bool with_texture) {
  nlohmann::json material = {{"name", "skin"},
                             {"pbrMetallicRoughness",
                              {{"baseColorFactor", options.base_color},
                               {"metallicFactor", 0.0},
                               {"roughnessFactor", options.roughness}}}};
  if (with_texture) {
    material["pbrMetallicRoughness"]["baseColorFactor"] = {1.0, 1.0, 1.0, 1.0};
    material["pbrMetallicRoughness"]["baseColorTexture"] = {{"index", 0}, {"texCoord", 0}};
  }
  return material;
}

// The glTF document of one mesh in one node, one material and one buffer; with an animation
// the mesh's node is the child of a "head" node (GlbAnimationNodes) that carries the head pose.
nlohmann::json document(const GlbOptions& options, const nlohmann::json& mesh,
                        const nlohmann::json& material) {
  nlohmann::json nodes = {{{"mesh", 0}, {"name", options.name}}};
  if (options.animation != nullptr)
    nodes = {{{"name", "head"}, {"children", {1}}}, {{"mesh", 0}, {"name", options.name}}};
  return {
      {"asset", {{"version", "2.0"}, {"generator", "facebooth"}}},
      {"scene", 0},
      {"scenes", {{{"nodes", {0}}}}},
      {"nodes", nodes},
      {"meshes", {mesh}},
      {"materials", {material}},
  };
}

}  // namespace

std::vector<float> vertex_tangents(const std::vector<float>& positions,
                                   const std::vector<float>& normals,
                                   const std::vector<float>& texcoords,
                                   const std::vector<std::uint32_t>& triangles) {
  const std::size_t n = positions.size() / 3;
  std::vector<Eigen::Vector3d> du(n, Eigen::Vector3d::Zero()), dv(n, Eigen::Vector3d::Zero());
  auto p = [&](std::uint32_t v) {
    return Eigen::Vector3d(positions[3 * v], positions[3 * v + 1], positions[3 * v + 2]);
  };
  // glTF's v runs down the image; the layout's +v (the normal map's green) is -v here.
  auto uv = [&](std::uint32_t v) {
    return Eigen::Vector2d(texcoords[2 * v], -texcoords[2 * v + 1]);
  };
  for (std::size_t t = 0; t + 2 < triangles.size(); t += 3) {
    const std::uint32_t a = triangles[t], b = triangles[t + 1], c = triangles[t + 2];
    const Eigen::Vector3d e1 = p(b) - p(a), e2 = p(c) - p(a);
    const Eigen::Vector2d f1 = uv(b) - uv(a), f2 = uv(c) - uv(a);
    const double det = f1.x() * f2.y() - f2.x() * f1.y();
    if (std::abs(det) < 1e-14) continue;
    // Surface per UV unit, area-weighted by summing unnormalised (|det| keeps its sign off).
    const Eigen::Vector3d su = (e1 * f2.y() - e2 * f1.y()) / det * std::abs(det);
    const Eigen::Vector3d sv = (e2 * f1.x() - e1 * f2.x()) / det * std::abs(det);
    for (const auto v : {a, b, c}) du[v] += su, dv[v] += sv;
  }
  std::vector<float> out(4 * n);
  for (std::size_t v = 0; v < n; ++v) {
    const Eigen::Vector3d nv(normals[3 * v], normals[3 * v + 1], normals[3 * v + 2]);
    Eigen::Vector3d t = du[v] - nv * nv.dot(du[v]);
    if (t.norm() < 1e-12) t = nv.unitOrthogonal();  // no UV extent: any tangent will do
    t.normalize();
    const double w = nv.cross(t).dot(dv[v]) < 0.0 ? -1.0 : 1.0;
    for (int k = 0; k < 3; ++k) out[4 * v + k] = static_cast<float>(t[k]);
    out[4 * v + 3] = static_cast<float>(w);
  }
  return out;
}

namespace {

// One texture per PNG in buffer views `image_views`, linear filtering with mipmaps, clamped so
// the atlas's borders do not wrap.
void add_textures(nlohmann::json& gltf, const std::vector<int>& image_views) {
  gltf["samplers"] = {
      {{"magFilter", 9729}, {"minFilter", 9987}, {"wrapS", 33071}, {"wrapT", 33071}}};
  for (std::size_t i = 0; i < image_views.size(); ++i) {
    gltf["images"].push_back({{"bufferView", image_views[i]}, {"mimeType", "image/png"}});
    gltf["textures"].push_back({{"sampler", 0}, {"source", i}});
  }
}

}  // namespace

Result<std::vector<std::uint8_t>> encode_glb(const RigData& rig, const GlbOptions& options) {
  const int nv = rig.vertex_count();
  if (nv == 0 || rig.triangles.empty()) return fail("cannot export an empty rig as glTF");
  if (rig.shape_names.size() != rig.shapes.size()) return fail("rig shape names do not match");
  if (options.animation != nullptr) {
    if (auto r = check_animation(*options.animation, rig.shape_count()); !r)
      return fail("cannot animate the glTF: " + r.error().message);
  }

  // Output vertices: one per (vertex, UV) corner pair with UVs, else the rig's own.
  const bool textured = options.uvs != nullptr && options.uvs->fits(rig.triangles);
  SplitMesh split;
  if (textured) {
    split = split_seams(rig.triangles, *options.uvs);
  } else {
    split.triangles = rig.triangles;
    split.source_vertex.resize(static_cast<std::size_t>(nv));
    for (int v = 0; v < nv; ++v) split.source_vertex[static_cast<std::size_t>(v)] = v;
  }
  const std::size_t out_count = split.source_vertex.size();
  // Per-output-vertex attribute from a per-rig-vertex one (3 floats each).
  auto gather = [&](const std::vector<float>& per_vertex, float scale) {
    std::vector<float> out(3 * out_count);
    for (std::size_t o = 0; o < out_count; ++o) {
      const std::size_t v = split.source_vertex[o];
      for (int k = 0; k < 3; ++k) out[3 * o + k] = per_vertex[3 * v + k] * scale;
    }
    return out;
  };

  GlbBuffer buffer;
  const int indices = buffer.add_indices(split.triangles);

  const std::vector<float> neutral = gather(rig.neutral, options.scale);
  const std::vector<float> neutral_normals = vertex_normals(rig.neutral, rig.triangles);
  nlohmann::json attributes = {
      {"POSITION", buffer.add_floats(neutral, 3, "VEC3")},
      {"NORMAL", buffer.add_floats(gather(neutral_normals, 1.0f), 3, "VEC3")}};
  const bool with_normal_map =
      textured && options.normal_png != nullptr && !options.normal_png->empty();
  if (textured) {
    const std::vector<float> texcoords = split_texcoords(split, options.uvs->uvs);
    attributes["TEXCOORD_0"] = buffer.add_floats(texcoords, 2, "VEC2");
    if (with_normal_map) {
      const std::vector<float> normals = gather(neutral_normals, 1.0f);
      attributes["TANGENT"] = buffer.add_floats(
          vertex_tangents(gather(rig.neutral, 1.0f), normals, texcoords, split.triangles), 4,
          "VEC4");
    }
  }

  nlohmann::json targets = nlohmann::json::array();
  std::vector<float> delta(rig.neutral.size());
  for (const auto& shape : rig.shapes) {
    for (std::size_t i = 0; i < delta.size(); ++i) delta[i] = shape[i] - rig.neutral[i];
    const int position = buffer.add_floats(gather(delta, options.scale), 3, "VEC3");
    const std::vector<float> normals = vertex_normals(shape, rig.triangles);
    for (std::size_t i = 0; i < delta.size(); ++i) delta[i] = normals[i] - neutral_normals[i];
    targets.push_back(
        {{"POSITION", position}, {"NORMAL", buffer.add_floats(gather(delta, 1.0f), 3, "VEC3")}});
  }

  nlohmann::json primitive = {
      {"attributes", attributes}, {"indices", indices}, {"mode", 4}, {"material", 0}};
  nlohmann::json mesh = {{"name", options.name}, {"primitives", {primitive}}};
  if (!rig.shapes.empty()) {
    mesh["primitives"][0]["targets"] = targets;
    mesh["weights"] = std::vector<float>(rig.shapes.size(), 0.0f);
    mesh["extras"] = {{"targetNames", rig.shape_names}};
  }
  // The base colour texture (a PNG in the UV layout), embedded in the binary chunk.
  const bool with_texture =
      textured && options.base_color_png != nullptr && !options.base_color_png->empty();
  nlohmann::json material = skin_material(options, with_texture);
  std::vector<int> image_views;
  if (with_texture)
    image_views.push_back(buffer.add_view(options.base_color_png->data(),
                                          options.base_color_png->size(), GlbBuffer::kNoTarget));
  if (with_normal_map) {
    image_views.push_back(buffer.add_view(options.normal_png->data(), options.normal_png->size(),
                                          GlbBuffer::kNoTarget));
    material["normalTexture"] = {{"index", image_views.size() - 1}, {"texCoord", 0}};
  }
  nlohmann::json gltf = document(options, mesh, material);
  if (!image_views.empty()) add_textures(gltf, image_views);
  if (options.animation != nullptr) add_animation(gltf, buffer, *options.animation, {});
  gltf["buffers"] = {{{"byteLength", buffer.size()}}};
  gltf["bufferViews"] = buffer.views();
  gltf["accessors"] = buffer.accessors();
  return pack_glb(gltf.dump(), buffer.take_bytes());
}

}  // namespace fb
