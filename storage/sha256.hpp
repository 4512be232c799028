// SHA-256 (FIPS 180-4) for data-file and export checksums. Self-contained so the device image
// needs no crypto library for what is only an integrity check.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

namespace fb {

class Sha256 {
 public:
  Sha256();
  void update(std::span<const std::uint8_t> bytes);
  void update(const void* data, std::size_t size) {
    update({static_cast<const std::uint8_t*>(data), size});
  }
  // Finishes and returns the lowercase hex digest; the object must not be updated afterwards.
  std::string hex_digest();

 private:
  void block(const std::uint8_t* p);
  std::array<std::uint32_t, 8> h_;
  std::array<std::uint8_t, 64> buffer_{};
  std::size_t buffered_ = 0;
  std::uint64_t total_ = 0;
};

std::string sha256_hex(std::span<const std::uint8_t> bytes);

}  // namespace fb
