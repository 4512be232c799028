// A .glb read back in tests: the JSON chunk, and the float data of an accessor (tightly packed
// views, as our writer makes them).
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <vector>

#include "storage/durable_file.hpp"

namespace fb::test {

struct Glb {
  nlohmann::json json;
  std::vector<std::uint8_t> bytes;
  std::size_t bin_offset = 0;
  std::vector<float> floats(int accessor) const {
    const auto& a = json["accessors"][accessor];
    const auto& v = json["bufferViews"][a["bufferView"].get<int>()];
    const std::string type = a["type"];
    const std::size_t per = type == "SCALAR" ? 1 : type == "VEC2" ? 2 : type == "VEC4" ? 4 : 3;
    const std::size_t count = a["count"].get<std::size_t>() * per;
    std::vector<float> out(count);
    std::memcpy(out.data(), bytes.data() + bin_offset + v["byteOffset"].get<std::size_t>(),
                count * sizeof(float));
    return out;
  }
};

inline Glb read_glb(const std::filesystem::path& path) {
  Glb glb;
  auto bytes = read_file_bytes(path);
  EXPECT_TRUE(bytes) << path;
  if (!bytes || bytes->size() < 28) return glb;
  glb.bytes = std::move(*bytes);
  std::uint32_t head[5];
  std::memcpy(head, glb.bytes.data(), sizeof head);
  glb.json = nlohmann::json::parse(glb.bytes.begin() + 20, glb.bytes.begin() + 20 + head[3]);
  glb.bin_offset = 20 + head[3] + 8;
  return glb;
}

}  // namespace fb::test
