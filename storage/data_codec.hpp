// Internal to storage/: the binary layouts of the session store's data files and their decoders,
// apart from the store so a fuzz target (tests/fuzz/store_files_fuzz.cpp) reaches them without
// a database. Layouts (all little-endian, written by memcpy; see storage/README.md):
//   .fbseq  "FBSEQ001", u32 frame count, u32 0, then frame_record records
//   .fbdep  "FBDEP001", i32 width, i32 height, u16 mm pixels
//   mesh    "FBMSH001", u32 vertices, u32 triangles, f32 xyz, u32 corners
//   rig     "FBRIG001", u32 vertices, u32 triangles, u32 shapes, neutral, shapes, u32 corners
//   take    "FBTAK002", u32 frames, u32 stride, f64 times, f32 values (FBTAK001: no times)
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <span>
#include <string>
#include <vector>

#include "algo/core/frame.hpp"
#include "algo/core/image.hpp"
#include "algo/core/result.hpp"
#include "storage/frame_record.hpp"
#include "storage/session_store.hpp"
#include "storage/stored_data.hpp"

namespace fb::store_detail {

class ByteWriter {
 public:
  template <class T>
  void put(T v) {
    const auto* p = reinterpret_cast<const std::uint8_t*>(&v);
    bytes.insert(bytes.end(), p, p + sizeof(T));
  }
  template <class T>
  void put_span(std::span<const T> v) {
    const auto* p = reinterpret_cast<const std::uint8_t*>(v.data());
    bytes.insert(bytes.end(), p, p + v.size_bytes());
  }
  void put_magic(const char (&magic)[9]) {
    // resize + memcpy, not insert: GCC 12 warns (-Wstringop-overflow) on an insert it inlines
    // into an empty vector.
    const std::size_t at = bytes.size();
    bytes.resize(at + 8);
    std::memcpy(bytes.data() + at, magic, 8);
  }
  std::vector<std::uint8_t> bytes;
};

class ByteReader {
 public:
  ByteReader(std::span<const std::uint8_t> bytes, std::size_t pos = 0) : bytes_(bytes), pos_(pos) {}
  template <class T>
  bool get(T& v) {
    if (bytes_.size() - pos_ < sizeof(T) || pos_ > bytes_.size()) return false;
    std::memcpy(&v, bytes_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return true;
  }
  template <class T>
  bool get_array(std::vector<T>& out, std::size_t count) {
    if (count > (bytes_.size() - pos_) / sizeof(T)) return false;
    out.resize(count);
    if (count > 0) std::memcpy(out.data(), bytes_.data() + pos_, count * sizeof(T));
    pos_ += count * sizeof(T);
    return true;
  }
  bool magic(const char (&m)[9]) {
    if (bytes_.size() - pos_ < 8 || std::memcmp(bytes_.data() + pos_, m, 8) != 0) return false;
    pos_ += 8;
    return true;
  }
  bool at_end() const { return pos_ == bytes_.size(); }

 private:
  std::span<const std::uint8_t> bytes_;
  std::size_t pos_;
};

inline constexpr char kSeqMagic[9] = "FBSEQ001";
inline constexpr char kDepthMagic[9] = "FBDEP001";
inline constexpr char kMeshMagic[9] = "FBMSH001";
inline constexpr char kRigMagic[9] = "FBRIG001";
inline constexpr char kTakeMagicV1[9] = "FBTAK001";  // pose + weights, no times (before v3)
inline constexpr char kTakeMagic[9] = "FBTAK002";    // times (f64), then pose + weights (f32)

template <class Pixel>
bool read_image(ByteReader& reader, int w, int h, Image<Pixel>& out) {
  if (w < 0 || h < 0 || w > 16384 || h > 16384) return false;
  std::vector<std::uint8_t> raw;
  if (!reader.get_array(raw, static_cast<std::size_t>(w) * h * sizeof(Pixel))) return false;
  out.resize(w, h);
  if (!raw.empty()) std::memcpy(out.pixels.data(), raw.data(), raw.size());
  return true;
}

// Decodes a .fbseq stream of `file_bytes` bytes holding `expected_count` frames into `frames`
// (the first `max_frames` decoded, the rest skipped). `in` has read(data, n) -> bool,
// skip(n) -> bool and position(): the store's VerifiedReader, or a buffer. `bad` is the error
// message; the caller decides from the checksum whether the file was damaged or malformed.
template <class Reader>
Result<void> decode_frame_sequence(Reader& in, std::uint64_t file_bytes, int expected_count,
                                   std::size_t max_frames, std::vector<RgbdFrame>& frames,
                                   const std::string& bad) {
  char magic[8];
  std::uint32_t count = 0, reserved = 0;
  if (!in.read(magic, 8) || std::memcmp(magic, kSeqMagic, 8) != 0 || !in.read(&count, 4) ||
      !in.read(&reserved, 4))
    return fail(bad);
  if (static_cast<std::int64_t>(count) != expected_count)
    return fail(bad + " (frame count differs)");
  const std::size_t keep = std::min<std::size_t>(count, max_frames);
  frames.resize(keep);
  auto source = [&](void* data, std::size_t size) { return in.read(data, size); };
  for (std::uint32_t i = 0; i < count; ++i) {
    frame_record::Header h{};
    if (!in.read(&h, sizeof h) || !frame_record::plausible(h)) return fail(bad);
    const std::uint64_t n = frame_record::pixel_bytes(h);
    if (in.position() > file_bytes || n > file_bytes - in.position()) return fail(bad);
    const bool decoded = i < keep ? frame_record::read_pixels(h, frames[i], source)
                                  : in.skip(static_cast<std::size_t>(n));
    if (!decoded) return fail(bad);
  }
  if (in.position() != file_bytes) return fail(bad + " (trailing bytes)");
  return success();
}

// The other data files, whole in memory. Each returns false on any inconsistency (wrong magic,
// sizes that do not match the header or the database row, an index out of range, trailing
// bytes); the caller names the file in its error.
bool decode_fused_depth(std::span<const std::uint8_t> bytes, DepthImage& out);
bool decode_mesh(std::span<const std::uint8_t> bytes, MeshData& mesh);
// `rig.shape_names` (from the database) must already be set: the file's shape count must match.
bool decode_rig(std::span<const std::uint8_t> bytes, RigData& rig);
// `take.info` (from the database) must already be set. `time_source` is the takes row's:
// "file" (FBTAK002), "frame_rate" or "last_column" (FBTAK001 from before schema v3).
bool decode_take(std::span<const std::uint8_t> bytes, const std::string& time_source,
                 TakeData& take);

}  // namespace fb::store_detail
