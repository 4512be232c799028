// Replay of the real Kinect dump shared/kinect/openiss-desk (90 depth frames of people at a desk).
#include <algorithm>
#include <chrono>
#include <cstring>
#include <iostream>

#include <gtest/gtest.h>

#include "drivers/camera/common/device_json.hpp"
#include "drivers/camera/replay/replay_camera.hpp"
#include "tests/camera_replay/test_dumps.hpp"

namespace fb {
namespace {

class RealDumpReplay : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string why;
    dir_ = test::real_dump_dir(why);
    if (dir_.empty()) GTEST_SKIP() << why;
  }
  std::filesystem::path dir_;
};

TEST_F(RealDumpReplay, NinetyFramesThenEndOfStream) {
  auto cam = replay_camera_backend().open(dir_.string());
  ASSERT_TRUE(cam) << cam.error().message;
  DepthCamera& camera = **cam;
  const CameraInfo& info = camera.info();
  EXPECT_EQ(info.backend, "replay");
  EXPECT_EQ(info.frame_count, 90);
  EXPECT_EQ(info.width, 640);
  EXPECT_EQ(info.height, 480);
  EXPECT_GT(info.fps, 20.0);
  EXPECT_LT(info.fps, 40.0);
  std::cout << "[ replay ] " << info.description << ", " << info.fps << " fps\n";
  EXPECT_NEAR(info.depth_intrinsics.fx, 575.8, 0.1);
  // Calibration comes from the dump's device.json (equal to the documented defaults).
  auto json = read_device_json(dir_ / "device.json");
  ASSERT_TRUE(json);
  EXPECT_EQ(to_device_json(info.calibration), to_device_json(*json));
  EXPECT_EQ(to_device_json(info.calibration), to_device_json(KinectCalibration::defaults()));

  ASSERT_TRUE(camera.start());
  const KinectRegistration reg(info.calibration);
  RgbdFrame frame;
  int frames = 0;
  double last_time = 0.0;
  std::vector<std::uint16_t> medians;
  for (;;) {
    auto status = camera.next_frame(frame, std::chrono::milliseconds(1000));
    ASSERT_TRUE(status) << status.error().message;
    if (*status == FrameStatus::kEndOfStream) break;
    ASSERT_EQ(*status, FrameStatus::kFrame);
    EXPECT_EQ(frame.index, static_cast<std::uint64_t>(frames));
    ASSERT_EQ(frame.depth_mm.width, 640);
    ASSERT_EQ(frame.raw_disparity.width, 640);
    ASSERT_EQ(frame.color.width, 640);
    ASSERT_EQ(frame.color.height, 480);
    EXPECT_GT(frame.depth_host_time_s, last_time);
    last_time = frame.depth_host_time_s;
    std::vector<std::uint16_t> valid;
    valid.reserve(frame.depth_mm.pixels.size());
    for (std::size_t i = 0; i < frame.depth_mm.pixels.size(); ++i) {
      const auto raw = frame.raw_disparity.pixels[i];
      ASSERT_LE(raw, kInvalidDisparity);
      ASSERT_EQ(frame.depth_mm.pixels[i], reg.raw_to_mm(raw));
      if (frame.depth_mm.pixels[i] != 0) valid.push_back(frame.depth_mm.pixels[i]);
    }
    // Most of the desk scene is measured, at desk distances.
    EXPECT_GT(valid.size(), frame.depth_mm.pixels.size() / 2) << "frame " << frames;
    std::nth_element(valid.begin(), valid.begin() + valid.size() / 2, valid.end());
    const auto median = valid[valid.size() / 2];
    EXPECT_GE(median, 500) << "frame " << frames;
    EXPECT_LE(median, 4000) << "frame " << frames;
    medians.push_back(median);
    ++frames;
  }
  EXPECT_EQ(frames, 90);
  // Still the end, not an error, when asked again.
  auto again = camera.next_frame(frame, std::chrono::milliseconds(0));
  ASSERT_TRUE(again);
  EXPECT_EQ(*again, FrameStatus::kEndOfStream);
  std::sort(medians.begin(), medians.end());
  std::cout << "[ replay ] median depth over frames: " << medians.front() << ".." << medians.back()
            << " mm\n";
}

TEST_F(RealDumpReplay, FirstPixelsAreLittleEndianDisparity) {
  // The first depth file starts with bytes c6 03 after its header: 0x03c6 = 966 raw, about 2.8 m.
  auto reader = FakenectDumpReader::open(dir_);
  ASSERT_TRUE(reader) << reader.error().message;
  RgbdFrame frame;
  ASSERT_TRUE(*reader->next(frame));
  EXPECT_EQ(frame.raw_disparity.pixels[1], 0x03c6);
  EXPECT_EQ(reader->entries().size(), 369u);
  EXPECT_EQ(reader->color_image_count(), 91u);
  // INDEX.txt starts r, d, a, a, d: the first frame has no accelerometer sample yet, the second
  // one does (gravity along +y, 819 counts per g).
  EXPECT_FALSE(reader->accel().has_value());
  ASSERT_TRUE(*reader->next(frame));
  ASSERT_TRUE(reader->accel().has_value());
  EXPECT_NEAR(reader->accel()->accelerometer_y, 819, 60);
}

TEST_F(RealDumpReplay, RestartAndThroughput) {
  auto cam = open_replay_camera(dir_);
  ASSERT_TRUE(cam) << cam.error().message;
  DepthCamera& camera = **cam;
  RgbdFrame frame;
  ASSERT_TRUE(camera.start());
  for (int i = 0; i < 5; ++i)
    ASSERT_EQ(*camera.next_frame(frame, std::chrono::milliseconds(0)), FrameStatus::kFrame);
  camera.stop();
  // start() begins at the first frame again. Time a full pass (informational, no assertion).
  ASSERT_TRUE(camera.start());
  const auto t0 = std::chrono::steady_clock::now();
  int n = 0;
  while (*camera.next_frame(frame, std::chrono::milliseconds(0)) == FrameStatus::kFrame) {
    if (n == 0) {
      EXPECT_EQ(frame.index, 0u);
    }
    ++n;
  }
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_EQ(n, 90);
  std::cout << "[ replay ] " << n << " frames in " << s << " s = " << n / s << " fps\n";
  RecordProperty("replay_fps", std::to_string(n / s));
}

TEST_F(RealDumpReplay, RealtimePacingDeliversInOrder) {
  auto cam = replay_camera_backend().open(dir_.string() + ",realtime=1");
  ASSERT_TRUE(cam) << cam.error().message;
  ASSERT_TRUE((*cam)->start());
  RgbdFrame frame;
  int frames = 0;
  int timeouts = 0;
  while (frames < 4) {
    auto s = (*cam)->next_frame(frame, std::chrono::milliseconds(1));
    ASSERT_TRUE(s);
    if (*s == FrameStatus::kTimeout) {
      ++timeouts;
      continue;
    }
    ASSERT_EQ(*s, FrameStatus::kFrame);
    EXPECT_EQ(frame.index, static_cast<std::uint64_t>(frames));
    ++frames;
  }
  std::cout << "[ replay ] realtime: " << timeouts
            << " timeouts of 1 ms while waiting for 4 frames\n";
}

// Issue 41: a sensor that stops mid-stream. stall_after=N delivers N frames and then times out
// (nothing arrives); fail_after=N delivers N and then fails, naming the fault.
TEST_F(RealDumpReplay, InjectedStallAndFailureAfterNFrames) {
  for (const char* fault : {"stall_after=3", "fail_after=3"}) {
    auto cam = replay_camera_backend().open(dir_.string() + "," + fault);
    ASSERT_TRUE(cam) << cam.error().message;
    ASSERT_TRUE((*cam)->start());
    RgbdFrame frame;
    for (int i = 0; i < 3; ++i) {
      auto s = (*cam)->next_frame(frame, std::chrono::milliseconds(20));
      ASSERT_TRUE(s) << fault;
      ASSERT_EQ(*s, FrameStatus::kFrame) << fault;
      EXPECT_EQ(frame.index, static_cast<std::uint64_t>(i));
    }
    for (int i = 0; i < 2; ++i) {
      auto s = (*cam)->next_frame(frame, std::chrono::milliseconds(20));
      if (std::string(fault).rfind("stall", 0) == 0) {
        ASSERT_TRUE(s);
        EXPECT_EQ(*s, FrameStatus::kTimeout);
      } else {
        ASSERT_FALSE(s);
        EXPECT_NE(s.error().message.find("failed after 3 frames"), std::string::npos)
            << s.error().message;
      }
    }
  }
  auto bad = replay_camera_backend().open(dir_.string() + ",stall_after=-2");
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().message.find("stall_after"), std::string::npos) << bad.error().message;
}

}  // namespace
}  // namespace fb
