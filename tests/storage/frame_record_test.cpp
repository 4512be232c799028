// storage/frame_record: the one encoding of an RGB-D frame (the store's .fbseq records and the
// device's take spool). Round trip with and without the raw disparity, and a damaged header
// refused before anything is allocated.
#include <gtest/gtest.h>

#include <cstring>
#include <vector>

#include "storage/frame_record.hpp"

namespace fb {
namespace {

RgbdFrame make_frame(int w, int h, std::uint64_t index) {
  RgbdFrame f;
  f.index = index;
  f.depth_host_time_s = 12.5 + static_cast<double>(index);
  f.color_host_time_s = 12.51 + static_cast<double>(index);
  f.depth_device_timestamp = 1000u + static_cast<std::uint32_t>(index);
  f.color_device_timestamp = 2000u;
  f.depth_mm.resize(w, h);
  f.raw_disparity.resize(w, h);
  f.color.resize(w, h);
  for (std::size_t i = 0; i < f.depth_mm.pixels.size(); ++i) {
    f.depth_mm.pixels[i] = static_cast<std::uint16_t>(500 + i);
    f.raw_disparity.pixels[i] = static_cast<std::uint16_t>(2047 - i);
    f.color.pixels[i] = {static_cast<std::uint8_t>(i), 7, static_cast<std::uint8_t>(255 - i)};
  }
  return f;
}

std::vector<std::uint8_t> encode(const RgbdFrame& f, bool with_raw) {
  std::vector<std::uint8_t> bytes;
  auto sink = [&](const void* data, std::size_t size) -> Result<void> {
    const auto* p = static_cast<const std::uint8_t*>(data);
    bytes.insert(bytes.end(), p, p + size);
    return success();
  };
  EXPECT_TRUE(frame_record::write(f, with_raw, sink));
  return bytes;
}

bool decode(const std::vector<std::uint8_t>& bytes, RgbdFrame& out) {
  std::size_t pos = 0;
  auto source = [&](void* data, std::size_t size) {
    if (bytes.size() - pos < size) return false;
    std::memcpy(data, bytes.data() + pos, size);
    pos += size;
    return true;
  };
  frame_record::Header h{};
  return source(&h, sizeof h) && frame_record::plausible(h) &&
         frame_record::read_pixels(h, out, source) && pos == bytes.size();
}

TEST(FrameRecord, RoundTripWithAndWithoutRawDisparity) {
  const RgbdFrame f = make_frame(8, 6, 3);
  const auto full = encode(f, true);
  EXPECT_EQ(full.size(), 56u + 48 * 2 + 48 * 2 + 48 * 3);
  EXPECT_EQ(frame_record::pixel_bytes(frame_record::header_of(f, true)), full.size() - 56);
  RgbdFrame back;
  ASSERT_TRUE(decode(full, back));
  EXPECT_EQ(back.index, 3u);
  EXPECT_DOUBLE_EQ(back.depth_host_time_s, 15.5);
  EXPECT_DOUBLE_EQ(back.color_host_time_s, 15.51);
  EXPECT_EQ(back.depth_device_timestamp, 1003u);
  EXPECT_EQ(back.color_device_timestamp, 2000u);
  EXPECT_EQ(back.depth_mm.pixels, f.depth_mm.pixels);
  EXPECT_EQ(back.raw_disparity.pixels, f.raw_disparity.pixels);
  EXPECT_EQ(std::memcmp(back.color.pixels.data(), f.color.pixels.data(), 48 * 3), 0);

  // The spool's form: no disparity, the header says 0 x 0, the rest is the same.
  const auto spool = encode(f, false);
  EXPECT_EQ(spool.size(), full.size() - 48 * 2);
  RgbdFrame back2 = make_frame(2, 2, 0);  // a reused frame: its old disparity goes away
  ASSERT_TRUE(decode(spool, back2));
  EXPECT_TRUE(back2.raw_disparity.empty());
  EXPECT_EQ(back2.depth_mm.pixels, f.depth_mm.pixels);
  EXPECT_EQ(back2.color.width, 8);

  // A truncated record fails; so does a header with an impossible size.
  auto truncated = full;
  truncated.resize(full.size() - 1);
  EXPECT_FALSE(decode(truncated, back));
  auto damaged = full;
  const std::int32_t huge = 1 << 20;
  std::memcpy(damaged.data() + offsetof(frame_record::Header, color_w), &huge, sizeof huge);
  EXPECT_FALSE(decode(damaged, back));
}

}  // namespace
}  // namespace fb
