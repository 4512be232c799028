// The binary side of a .glb (storage/export internal): one buffer of views and accessors
// that the mesh (gltf.cpp) and the animation (gltf_animation.cpp) append to, and the GLB
// container around the JSON and that buffer.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "algo/core/result.hpp"

namespace fb {

class GlbBuffer {
 public:
  static constexpr int kArrayBuffer = 34962;         // vertex attributes
  static constexpr int kElementArrayBuffer = 34963;  // indices
  static constexpr int kNoTarget = 0;                // images, animation samplers

  // A buffer view over a copy of `bytes` bytes, padded to 4 so accessors stay aligned.
  int add_view(const void* data, std::size_t bytes, int target);
  // A float accessor of `components` per element with exact min/max (required for POSITION
  // and animation inputs).
  int add_floats(std::span<const float> values, int components, const char* type,
                 int target = kArrayBuffer);
  int add_indices(std::span<const std::uint32_t> indices);

  std::size_t size() const { return bin_.size(); }
  const nlohmann::json& views() const { return views_; }
  const nlohmann::json& accessors() const { return accessors_; }
  std::vector<std::uint8_t> take_bytes() { return std::move(bin_); }

 private:
  std::vector<std::uint8_t> bin_;
  nlohmann::json views_ = nlohmann::json::array();
  nlohmann::json accessors_ = nlohmann::json::array();
};

// The .glb container: header, the JSON chunk and the binary chunk, each padded to 4 bytes.
Result<std::vector<std::uint8_t>> pack_glb(std::string json, std::vector<std::uint8_t> bin);

}  // namespace fb
