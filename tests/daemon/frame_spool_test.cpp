// The device's take spool writes the session store's frame record (storage/frame_record.hpp):
// frames read back equal what went in (without the disparity, which the spool does not keep),
// and the spool file is exactly the records one after another.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>

#include "firmware/daemon/frame_spool.hpp"
#include "storage/frame_record.hpp"

namespace fb {
namespace {

namespace fs = std::filesystem;

TEST(FrameSpool, WritesTheStoresFrameRecord) {
  const fs::path dir = fs::temp_directory_path() / ("fb-frame-spool-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  std::vector<std::uint8_t> expected;
  fs::path file;
  {
    auto spool = FrameSpool::create(dir);
    ASSERT_TRUE(spool) << spool.error().message;
    std::vector<RgbdFrame> frames(3);
    for (int k = 0; k < 3; ++k) {
      RgbdFrame& f = frames[static_cast<std::size_t>(k)];
      f.index = static_cast<std::uint64_t>(10 + k);
      f.depth_host_time_s = 1.0 + k / 30.0;
      f.color_host_time_s = 1.01 + k / 30.0;
      f.depth_device_timestamp = 77u * static_cast<std::uint32_t>(k);
      f.depth_mm.resize(6, 4);
      f.raw_disparity.resize(6, 4);
      f.color.resize(6, 4);
      for (std::size_t i = 0; i < 24; ++i) {
        f.depth_mm.pixels[i] = static_cast<std::uint16_t>(600 + 10 * k + i);
        f.raw_disparity.pixels[i] = 1;
        f.color.pixels[i] = {static_cast<std::uint8_t>(k), static_cast<std::uint8_t>(i), 9};
      }
      ASSERT_TRUE((*spool)->append(f));
      auto sink = [&](const void* data, std::size_t size) -> Result<void> {
        const auto* p = static_cast<const std::uint8_t*>(data);
        expected.insert(expected.end(), p, p + size);
        return success();
      };
      ASSERT_TRUE(frame_record::write(f, /*with_raw_disparity=*/false, sink));
    }
    ASSERT_EQ((*spool)->size(), 3u);
    RgbdFrame back;
    for (int k = 2; k >= 0; --k) {  // any order
      ASSERT_TRUE((*spool)->read(static_cast<std::size_t>(k), back));
      const RgbdFrame& f = frames[static_cast<std::size_t>(k)];
      EXPECT_EQ(back.index, f.index);
      EXPECT_DOUBLE_EQ(back.depth_host_time_s, f.depth_host_time_s);
      EXPECT_DOUBLE_EQ(back.color_host_time_s, f.color_host_time_s);
      EXPECT_EQ(back.depth_device_timestamp, f.depth_device_timestamp);
      EXPECT_EQ(back.depth_mm.pixels, f.depth_mm.pixels);
      EXPECT_EQ(std::memcmp(back.color.pixels.data(), f.color.pixels.data(), 24 * 3), 0);
      EXPECT_TRUE(back.raw_disparity.empty());
    }
    EXPECT_FALSE((*spool)->read(3, back));
    file = (*spool)->path();
    std::ifstream in(file, std::ios::binary);
    const std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                          std::istreambuf_iterator<char>());
    EXPECT_EQ(bytes, expected);  // the same bytes the store's codec writes
  }
  EXPECT_FALSE(fs::exists(file));  // the spool is scratch: gone with the object
  fs::remove_all(dir);
}

}  // namespace
}  // namespace fb
