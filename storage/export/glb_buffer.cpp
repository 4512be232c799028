#include "storage/export/glb_buffer.hpp"

#include <algorithm>
#include <cstring>
#include <limits>

namespace fb {

namespace {

constexpr std::uint32_t kGlbMagic = 0x46546C67;  // "glTF"
constexpr std::uint32_t kJsonChunk = 0x4E4F534A;
constexpr std::uint32_t kBinChunk = 0x004E4942;
constexpr int kFloat = 5126;
constexpr int kUnsignedInt = 5125;

}  // namespace

int GlbBuffer::add_view(const void* data, std::size_t bytes, int target) {
  const std::size_t offset = bin_.size();
  bin_.resize(offset + bytes);
  if (bytes > 0) std::memcpy(bin_.data() + offset, data, bytes);
  while (bin_.size() % 4 != 0) bin_.push_back(0);
  nlohmann::json view = {{"buffer", 0}, {"byteOffset", offset}, {"byteLength", bytes}};
  if (target != kNoTarget) view["target"] = target;
  views_.push_back(view);
  return static_cast<int>(views_.size() - 1);
}

int GlbBuffer::add_floats(std::span<const float> values, int components, const char* type,
                          int target) {
  const auto dim = static_cast<std::size_t>(components);
  std::vector<float> lo(dim, std::numeric_limits<float>::max());
  std::vector<float> hi(dim, std::numeric_limits<float>::lowest());
  for (std::size_t i = 0; i < values.size(); ++i) {
    lo[i % dim] = std::min(lo[i % dim], values[i]);
    hi[i % dim] = std::max(hi[i % dim], values[i]);
  }
  const int view = add_view(values.data(), values.size() * sizeof(float), target);
  accessors_.push_back({{"bufferView", view},
                        {"componentType", kFloat},
                        {"count", values.size() / dim},
                        {"type", type},
                        {"min", lo},
                        {"max", hi}});
  return static_cast<int>(accessors_.size() - 1);
}

int GlbBuffer::add_indices(std::span<const std::uint32_t> indices) {
  const int view =
      add_view(indices.data(), indices.size() * sizeof(std::uint32_t), kElementArrayBuffer);
  accessors_.push_back({{"bufferView", view},
                        {"componentType", kUnsignedInt},
                        {"count", indices.size()},
                        {"type", "SCALAR"}});
  return static_cast<int>(accessors_.size() - 1);
}

Result<std::vector<std::uint8_t>> pack_glb(std::string json, std::vector<std::uint8_t> bin) {
  while (json.size() % 4 != 0) json.push_back(' ');
  while (bin.size() % 4 != 0) bin.push_back(0);
  const std::size_t total = 12 + 8 + json.size() + 8 + bin.size();
  if (total > std::numeric_limits<std::uint32_t>::max())
    return fail("the glTF is " + std::to_string(total >> 20) +
                " MB, over the .glb format's 4 GB limit");
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
