// The session store's data files (storage/data_codec): .fbseq frame sequences (frame_record),
// .fbdep fused depth, mesh, rig and take files, as read_capture/read_mesh/read_rig/read_take
// decode them. The store checks each file's size and SHA-256 against its database first; these
// decoders are what stands between a file written wrong (or a database row that lies about it)
// and the readers. The first byte picks the file type, the rest is the file.
#include <algorithm>
#include <cstring>

#include "storage/data_codec.hpp"
#include "tests/fuzz/fuzz_util.hpp"

namespace {

// The store's VerifiedReader, over a buffer.
class BufferReader {
 public:
  explicit BufferReader(std::span<const std::uint8_t> bytes) : bytes_(bytes) {}
  bool read(void* out, std::size_t n) {
    const std::size_t got = std::min(n, bytes_.size() - position_);
    if (got > 0) std::memcpy(out, bytes_.data() + position_, got);
    position_ += got;
    return got == n;
  }
  bool skip(std::size_t n) {
    const std::size_t got = std::min(n, bytes_.size() - position_);
    position_ += got;
    return got == n;
  }
  std::uint64_t position() const { return position_; }

 private:
  std::span<const std::uint8_t> bytes_;
  std::size_t position_ = 0;
};

// The database's frame count: what the file's own header says, so decoding goes on past it.
int declared_frames(std::span<const std::uint8_t> file) {
  std::uint32_t count = 0;
  if (file.size() >= 12) std::memcpy(&count, file.data() + 8, 4);
  return static_cast<int>(std::min<std::uint32_t>(count, 1u << 20));
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  using namespace fb::store_detail;
  const std::span<const std::uint8_t> file(data + 1, size - 1);
  switch (data[0] % 6) {
    case 0: {
      BufferReader in(file);
      std::vector<fb::RgbdFrame> frames;
      (void)decode_frame_sequence(in, file.size(), declared_frames(file), 2, frames, "bad");
      break;
    }
    case 1: {
      fb::DepthImage depth;
      (void)decode_fused_depth(file, depth);
      break;
    }
    case 2: {
      fb::MeshData mesh;
      if (decode_mesh(file, mesh)) {
        for (auto t : mesh.triangles)
          fb::fuzz::require(static_cast<int>(t) < mesh.vertex_count(), "mesh index in range");
      }
      break;
    }
    case 3: {
      fb::RigData rig;
      rig.shape_names = {"jawOpen", "mouthSmile_L"};
      if (decode_rig(file, rig)) {
        for (const auto& s : rig.shapes)
          fb::fuzz::require(s.size() == rig.neutral.size(), "rig shapes match the neutral");
      }
      break;
    }
    default: {
      // A take row with two shapes, as many frames as the file says; each time source.
      fb::TakeData take;
      take.info.shape_names = {"jawOpen", "mouthSmile_L"};
      take.info.frame_count = declared_frames(file);
      const char* source =
          data[0] % 6 == 4 ? "file" : (data[0] & 0x80 ? "last_column" : "frame_rate");
      if (decode_take(file, source, take)) {
        fb::fuzz::require(take.values.size() == std::size_t(take.info.frame_count) *
                                                    std::size_t(take.info.stride()) &&
                              take.times_s.size() == std::size_t(take.info.frame_count),
                          "a decoded take has frame_count rows");
      }
      break;
    }
  }
  return 0;
}
