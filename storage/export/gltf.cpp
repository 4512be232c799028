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

}  // namespace

Result<std::vector<std::uint8_t>> encode_glb(const RigData& rig, const GlbOptions& options) {
  const int nv = rig.vertex_count();
  if (nv == 0 || rig.triangles.empty()) return fail("cannot export an empty rig as glTF");
  if (rig.shape_names.size() != rig.shapes.size()) return fail("rig shape names do not match");

  std::vector<std::uint8_t> bin;
  nlohmann::json views = nlohmann::json::array();
  nlohmann::json accessors = nlohmann::json::array();
  auto add_view = [&](const void* data, std::size_t bytes, int target) {
    const std::size_t offset = bin.size();  // every block is a multiple of 4 bytes
    bin.resize(offset + bytes);
    std::memcpy(bin.data() + offset, data, bytes);
    views.push_back(
        {{"buffer", 0}, {"byteOffset", offset}, {"byteLength", bytes}, {"target", target}});
    return static_cast<int>(views.size() - 1);
  };
  // A VEC3 float accessor; min/max are required for POSITION and must be exact.
  auto add_vec3 = [&](const std::vector<float>& values) {
    float lo[3], hi[3];
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::numeric_limits<float>::max();
      hi[k] = std::numeric_limits<float>::lowest();
    }
    for (std::size_t i = 0; i < values.size(); ++i) {
      lo[i % 3] = std::min(lo[i % 3], values[i]);
      hi[i % 3] = std::max(hi[i % 3], values[i]);
    }
    const int view = add_view(values.data(), values.size() * sizeof(float), kArrayBuffer);
    accessors.push_back({{"bufferView", view},
                         {"componentType", kFloat},
                         {"count", values.size() / 3},
                         {"type", "VEC3"},
                         {"min", {lo[0], lo[1], lo[2]}},
                         {"max", {hi[0], hi[1], hi[2]}}});
    return static_cast<int>(accessors.size() - 1);
  };

  const int indices_view = add_view(
      rig.triangles.data(), rig.triangles.size() * sizeof(std::uint32_t), kElementArrayBuffer);
  accessors.push_back({{"bufferView", indices_view},
                       {"componentType", kUnsignedInt},
                       {"count", rig.triangles.size()},
                       {"type", "SCALAR"}});
  const int indices = 0;

  std::vector<float> neutral(rig.neutral.size());
  for (std::size_t i = 0; i < neutral.size(); ++i) neutral[i] = rig.neutral[i] * options.scale;
  const int position = add_vec3(neutral);

  nlohmann::json targets = nlohmann::json::array();
  std::vector<float> delta(rig.neutral.size());
  for (const auto& shape : rig.shapes) {
    for (std::size_t i = 0; i < delta.size(); ++i) {
      delta[i] = shape[i] * options.scale - neutral[i];
    }
    targets.push_back({{"POSITION", add_vec3(delta)}});
  }

  nlohmann::json primitive = {
      {"attributes", {{"POSITION", position}}}, {"indices", indices}, {"mode", 4}};
  nlohmann::json mesh = {{"name", options.name}, {"primitives", {primitive}}};
  if (!rig.shapes.empty()) {
    mesh["primitives"][0]["targets"] = targets;
    mesh["weights"] = std::vector<float>(rig.shapes.size(), 0.0f);
    mesh["extras"] = {{"targetNames", rig.shape_names}};
  }
  nlohmann::json gltf = {
      {"asset", {{"version", "2.0"}, {"generator", "facebooth"}}},
      {"scene", 0},
      {"scenes", {{{"nodes", {0}}}}},
      {"nodes", {{{"mesh", 0}, {"name", options.name}}}},
      {"meshes", {mesh}},
      {"buffers", {{{"byteLength", bin.size()}}}},
      {"bufferViews", views},
      {"accessors", accessors},
  };
  std::string json = gltf.dump();
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

}  // namespace fb
