// The openni2 backend as the rest of the project reaches it: through open_camera() and
// list_cameras().
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <string>

#include "drivers/camera/depth_camera.hpp"
#include "drivers/camera/openni2/oni_writer.hpp"

namespace fb {
namespace {

TEST(Openni2Registry, BuiltAndOpensRecordingsByUri) {
  const auto backends = built_camera_backends();
  ASSERT_NE(std::find(backends.begin(), backends.end(), "openni2"), backends.end());

  const auto path = std::filesystem::temp_directory_path() /
                    ("fb_openni2_registry_" + std::to_string(::getpid()) + ".oni");
  {
    OniWriterOptions options;
    options.width = 64;
    options.height = 48;
    auto writer = OniWriter::create(path, options);
    ASSERT_TRUE(writer) << writer.error().message;
    DepthImage depth;
    ColorImage color;
    depth.resize(64, 48);
    color.resize(64, 48);
    for (int k = 0; k < 3; ++k) {
      std::fill(depth.pixels.begin(), depth.pixels.end(), static_cast<std::uint16_t>(1000 + k));
      std::fill(color.pixels.begin(), color.pixels.end(), Rgb8{static_cast<std::uint8_t>(k), 2, 3});
      ASSERT_TRUE((*writer)->write(depth, color, 33333u * k));
    }
    ASSERT_TRUE((*writer)->close());
  }

  auto camera = open_camera("openni2:" + path.string());
  ASSERT_TRUE(camera) << camera.error().message;
  EXPECT_EQ((*camera)->info().backend, "openni2");
  EXPECT_EQ((*camera)->info().frame_count, 3);
  ASSERT_TRUE((*camera)->start());
  RgbdFrame frame;
  for (int k = 0; k < 3; ++k) {
    auto status = (*camera)->next_frame(frame, std::chrono::milliseconds(5000));
    ASSERT_TRUE(status) << status.error().message;
    ASSERT_EQ(*status, FrameStatus::kFrame);
    EXPECT_EQ(frame.depth_mm.at(10, 10), 1000 + k);
    EXPECT_EQ(frame.color.at(10, 10).r, k);
  }
  auto status = (*camera)->next_frame(frame, std::chrono::milliseconds(1000));
  ASSERT_TRUE(status);
  EXPECT_EQ(*status, FrameStatus::kEndOfStream);
  camera = fail("closed");  // destroy the camera before removing its file
  std::filesystem::remove(path);

  for (const auto& listing : list_cameras()) {
    EXPECT_EQ(listing.uri.find(".oni"), std::string::npos) << listing.uri;
  }
}

}  // namespace
}  // namespace fb
