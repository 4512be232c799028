#include "storage/export/gltf.hpp"

#include <algorithm>
#include <cstring>
#include <limits>
#include <nlohmann/json.hpp>

namespace fb {

namespace {

constexpr std::uint32_t kGlbMagic = 0x46546C67;  // "glTF"
constexpr std::uint32_t kJsonChunk = 0x4E4F534A;
constexpr std::uint32_t kBinChunk = 0x004E4942;
constexpr int kFloat = 5126;
constexpr int kUnsignedInt = 5125;
constexpr int kArrayBuffer = 34962;
constexpr int kElementArrayBuffer = 34963;

// The .glb container: header, the JSON chunk and the binary chunk, each padded to 4 bytes.
Result<std::vector<std::uint8_t>> pack_glb(std::string json, std::vector<std::uint8_t> bin) {
  while (json.size() % 4 != 0) json.push_back(' ');
  while (bin.size() % 4 != 0) bin.push_back(0);
  const std::size_t total = 12 + 8 + json.size() + 8 + bin.size();
  if (total > std::numeric_limits<std::uint32_t>::max()) return fail("rig too large for a .glb");
  std::vector<std::uint8_t> out(total);
  std::uint8_t* p = out.data();
  auto put32 = [&](std::uint32_t v) {
    std::memcpy(p, &v, 4);  // glb is little-endian, like the hosts we build for
    p += 4;
  };
  put32(kGlbMagic);
  put32(2);
  put32(static_cast<std::uint32_t>(total));
  put32(static_cast<std::uint32_t>(json.size()));
  put32(kJsonChunk);
  std::memcpy(p, json.data(), json.size());
  p += json.size();
  put32(static_cast<std::uint32_t>(bin.size()));
  put32(kBinChunk);
  std::memcpy(p, bin.data(), bin.size());
  return out;
}

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

// Texture 0: the PNG in buffer view `image_view`, linear filtering with mipmaps, clamped so
// the atlas's borders do not wrap.
void add_texture(nlohmann::json& gltf, int image_view) {
  gltf["images"] = {{{"bufferView", image_view}, {"mimeType", "image/png"}}};
  gltf["samplers"] = {
      {{"magFilter", 9729}, {"minFilter", 9987}, {"wrapS", 33071}, {"wrapT", 33071}}};
  gltf["textures"] = {{{"sampler", 0}, {"source", 0}}};
}

}  // namespace

Result<std::vector<std::uint8_t>> encode_glb(const RigData& rig, const GlbOptions& options) {
  const int nv = rig.vertex_count();
  if (nv == 0 || rig.triangles.empty()) return fail("cannot export an empty rig as glTF");
  if (rig.shape_names.size() != rig.shapes.size()) return fail("rig shape names do not match");

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

  std::vector<std::uint8_t> bin;
  nlohmann::json views = nlohmann::json::array();
  nlohmann::json accessors = nlohmann::json::array();
  // target 0: no target (an image); blocks are padded to 4 bytes so accessors stay aligned.
  auto add_view = [&](const void* data, std::size_t bytes, int target) {
    const std::size_t offset = bin.size();
    bin.resize(offset + bytes);
    std::memcpy(bin.data() + offset, data, bytes);
    while (bin.size() % 4 != 0) bin.push_back(0);
    nlohmann::json view = {{"buffer", 0}, {"byteOffset", offset}, {"byteLength", bytes}};
    if (target != 0) view["target"] = target;
    views.push_back(view);
    return static_cast<int>(views.size() - 1);
  };
  // A float accessor of `components` per element; min/max (required for POSITION) are exact.
  auto add_floats = [&](const std::vector<float>& values, int components, const char* type) {
    std::vector<float> lo(static_cast<std::size_t>(components), std::numeric_limits<float>::max());
    std::vector<float> hi(static_cast<std::size_t>(components),
                          std::numeric_limits<float>::lowest());
    for (std::size_t i = 0; i < values.size(); ++i) {
      const std::size_t k = i % static_cast<std::size_t>(components);
      lo[k] = std::min(lo[k], values[i]);
      hi[k] = std::max(hi[k], values[i]);
    }
    const int view = add_view(values.data(), values.size() * sizeof(float), kArrayBuffer);
    accessors.push_back({{"bufferView", view},
                         {"componentType", kFloat},
                         {"count", values.size() / static_cast<std::size_t>(components)},
                         {"type", type},
                         {"min", lo},
                         {"max", hi}});
    return static_cast<int>(accessors.size() - 1);
  };

  const int indices_view = add_view(
      split.triangles.data(), split.triangles.size() * sizeof(std::uint32_t), kElementArrayBuffer);
  accessors.push_back({{"bufferView", indices_view},
                       {"componentType", kUnsignedInt},
                       {"count", split.triangles.size()},
                       {"type", "SCALAR"}});
  const int indices = 0;

  const std::vector<float> neutral = gather(rig.neutral, options.scale);
  const std::vector<float> neutral_normals = vertex_normals(rig.neutral, rig.triangles);
  nlohmann::json attributes = {{"POSITION", add_floats(neutral, 3, "VEC3")},
                               {"NORMAL", add_floats(gather(neutral_normals, 1.0f), 3, "VEC3")}};
  if (textured) {
    attributes["TEXCOORD_0"] = add_floats(split_texcoords(split, options.uvs->uvs), 2, "VEC2");
  }

  nlohmann::json targets = nlohmann::json::array();
  std::vector<float> delta(rig.neutral.size());
  for (const auto& shape : rig.shapes) {
    for (std::size_t i = 0; i < delta.size(); ++i) delta[i] = shape[i] - rig.neutral[i];
    const int position = add_floats(gather(delta, options.scale), 3, "VEC3");
    const std::vector<float> normals = vertex_normals(shape, rig.triangles);
    for (std::size_t i = 0; i < delta.size(); ++i) delta[i] = normals[i] - neutral_normals[i];
    targets.push_back(
        {{"POSITION", position}, {"NORMAL", add_floats(gather(delta, 1.0f), 3, "VEC3")}});
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
  const int image_view =
      with_texture ? add_view(options.base_color_png->data(), options.base_color_png->size(), 0)
                   : -1;
  const nlohmann::json material = skin_material(options, with_texture);
  nlohmann::json gltf = {
      {"asset", {{"version", "2.0"}, {"generator", "facebooth"}}},
      {"scene", 0},
      {"scenes", {{{"nodes", {0}}}}},
      {"nodes", {{{"mesh", 0}, {"name", options.name}}}},
      {"meshes", {mesh}},
      {"materials", {material}},
      {"buffers", {{{"byteLength", bin.size()}}}},
      {"bufferViews", views},
      {"accessors", accessors},
  };
  if (with_texture) add_texture(gltf, image_view);
  return pack_glb(gltf.dump(), std::move(bin));
}

}  // namespace fb
