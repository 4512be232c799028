// FakenectRecorder / record_camera: record from a backend, replay the recording, compare.
#include "drivers/camera/recorder/recorder.hpp"

#include <cmath>

#include <gtest/gtest.h>

#include "drivers/camera/common/device_json.hpp"
#include "drivers/camera/replay/replay_camera.hpp"
#include "tests/camera_replay/test_dumps.hpp"

namespace fb {
namespace {

using test::TempDir;

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

// Reads every frame of a camera after start().
std::vector<RgbdFrame> read_all(DepthCamera& camera) {
  std::vector<RgbdFrame> frames;
  EXPECT_TRUE(camera.start());
  for (;;) {
    RgbdFrame f;
    auto s = camera.next_frame(f, std::chrono::milliseconds(1000));
    EXPECT_TRUE(s) << (s ? "" : s.error().message);
    if (!s || *s == FrameStatus::kEndOfStream) break;
    if (*s == FrameStatus::kFrame) frames.push_back(std::move(f));
  }
  camera.stop();
  return frames;
}

TEST(Recorder, RealDumpRoundTripIsIdentical) {
  std::string why;
  const auto source = test::real_dump_dir(why);
  if (source.empty()) GTEST_SKIP() << why;
  TempDir out("record_real");
  const auto target = out.path() / "recording";

  // Through the registry, as the product opens cameras.
  auto cam = open_camera("replay:" + source.string());
  ASSERT_TRUE(cam) << cam.error().message;
  long long progress_calls = 0;
  auto summary = record_camera(**cam, target, 0, [&](long long n) { progress_calls = n; });
  ASSERT_TRUE(summary) << summary.error().message;
  EXPECT_EQ(summary->depth_frames, 90);
  EXPECT_EQ(progress_calls, 90);
  EXPECT_TRUE(summary->end_of_stream);
  EXPECT_GT(summary->color_images, 80);
  EXPECT_LE(summary->color_images, 90);

  auto replayed = open_camera("replay:" + target.string());
  ASSERT_TRUE(replayed) << replayed.error().message;
  EXPECT_EQ(to_device_json((*replayed)->info().calibration),
            to_device_json((*cam)->info().calibration));
  const auto a = read_all(**cam);
  const auto b = read_all(**replayed);
  ASSERT_EQ(a.size(), 90u);
  ASSERT_EQ(b.size(), a.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    SCOPED_TRACE("frame " + std::to_string(i));
    EXPECT_EQ(a[i].index, b[i].index);
    EXPECT_EQ(a[i].raw_disparity.pixels, b[i].raw_disparity.pixels);
    EXPECT_EQ(a[i].depth_mm.pixels, b[i].depth_mm.pixels);
    ASSERT_EQ(a[i].color.pixels.size(), b[i].color.pixels.size());
    EXPECT_EQ(0, std::memcmp(a[i].color.pixels.data(), b[i].color.pixels.data(),
                             a[i].color.pixels.size() * sizeof(Rgb8)));
    EXPECT_NEAR(a[i].depth_host_time_s, b[i].depth_host_time_s, 1e-6);
    EXPECT_NEAR(a[i].color_host_time_s, b[i].color_host_time_s, 1e-6);
    EXPECT_EQ(a[i].depth_device_timestamp, b[i].depth_device_timestamp);
    EXPECT_EQ(a[i].color_device_timestamp, b[i].color_device_timestamp);
  }
}

TEST(Recorder, MaxFramesAndOverwriteRules) {
  TempDir dir("record_synth");
  {
    auto w = FakenectDumpWriter::create(dir.path() / "src", KinectCalibration::defaults());
    ASSERT_TRUE(w);
    for (int i = 0; i < 6; ++i) {
      ASSERT_TRUE(w->write_color(test::test_color(i), 1.0 + i * 0.033, i));
      ASSERT_TRUE(w->write_depth(test::test_disparity(i), 1.01 + i * 0.033, i));
    }
  }
  auto cam = open_replay_camera(dir.path() / "src");
  ASSERT_TRUE(cam) << cam.error().message;
  auto first = record_camera(**cam, dir.path() / "out", 4, {});
  ASSERT_TRUE(first) << first.error().message;
  EXPECT_EQ(first->depth_frames, 4);
  EXPECT_EQ(first->color_images, 4);
  EXPECT_FALSE(first->end_of_stream);

  auto refused = record_camera(**cam, dir.path() / "out", 4, {});
  ASSERT_FALSE(refused);
  EXPECT_TRUE(contains(refused.error().message, "not empty")) << refused.error().message;

  RecorderOptions overwrite;
  overwrite.overwrite = true;
  auto second = record_camera(**cam, dir.path() / "out", 0, {}, overwrite);
  ASSERT_TRUE(second) << second.error().message;
  EXPECT_EQ(second->depth_frames, 6);
  auto reader = FakenectDumpReader::open(dir.path() / "out");
  ASSERT_TRUE(reader);
  EXPECT_EQ(reader->depth_frame_count(), 6u);
  EXPECT_EQ(reader->entries().size(), 12u);
}

TEST(Recorder, MillimetreOnlyFramesAreQuantisedToRaw) {
  // A backend without raw disparity (openni2-like): depth_mm only, no timestamps, no colour.
  TempDir dir("record_mm");
  CameraInfo info;
  info.calibration = KinectCalibration::defaults();
  info.fps = 30.0;
  auto rec = FakenectRecorder::create(dir.path(), info);
  ASSERT_TRUE(rec) << rec.error().message;
  std::vector<DepthImage> written;
  for (int i = 0; i < 3; ++i) {
    RgbdFrame f;
    f.index = static_cast<std::uint64_t>(i);
    f.depth_mm.resize(640, 480);
    for (int y = 0; y < 480; ++y)
      for (int x = 0; x < 640; ++x)
        f.depth_mm.at(x, y) = static_cast<std::uint16_t>(600 + x * 3 + y + i);
    f.depth_mm.at(0, 0) = 0;
    ASSERT_TRUE(rec->write(f));
    written.push_back(f.depth_mm);
  }
  RgbdFrame empty;
  auto nothing = rec->write(empty);
  ASSERT_FALSE(nothing);
  EXPECT_TRUE(contains(nothing.error().message, "neither raw disparity nor depth"));
  auto summary = rec->finish();
  ASSERT_TRUE(summary);
  EXPECT_EQ(summary->depth_frames, 3);
  EXPECT_EQ(summary->color_images, 0);
  EXPECT_NEAR(summary->last_host_time_s, 2.0 / 30.0, 1e-9);

  auto cam = open_replay_camera(dir.path());
  ASSERT_TRUE(cam) << cam.error().message;
  EXPECT_NEAR((*cam)->info().fps, 30.0, 0.01);
  const auto frames = read_all(**cam);
  ASSERT_EQ(frames.size(), 3u);
  const KinectRegistration reg(KinectCalibration::defaults());
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_TRUE(frames[i].color.empty());
    for (std::size_t p = 0; p < written[i].pixels.size(); p += 97) {
      const auto z = written[i].pixels[p];
      ASSERT_EQ(frames[i].depth_mm.pixels[p], reg.raw_to_mm(reg.mm_to_raw(z))) << p;
    }
    EXPECT_EQ(frames[i].depth_mm.pixels[0], 0);
  }
}

// A camera that never delivers, or fails after a few frames.
class StuckCamera final : public DepthCamera {
 public:
  explicit StuckCamera(int frames_before_error) : frames_before_error_(frames_before_error) {
    info_.uri = "test:stuck";
    info_.calibration = KinectCalibration::defaults();
  }
  const CameraInfo& info() const override { return info_; }
  Result<void> start() override {
    started_ = true;
    return success();
  }
  void stop() override { started_ = false; }
  Result<FrameStatus> next_frame(RgbdFrame& frame, std::chrono::milliseconds) override {
    if (frames_before_error_ < 0) return FrameStatus::kTimeout;
    if (delivered_ == frames_before_error_) return fail("device unplugged");
    frame.raw_disparity = test::test_disparity(delivered_);
    frame.index = static_cast<std::uint64_t>(delivered_++);
    return FrameStatus::kFrame;
  }
  bool started_ = false;

 private:
  CameraInfo info_;
  int frames_before_error_;
  int delivered_ = 0;
};

TEST(Recorder, CameraProblemsLeaveAValidDump) {
  TempDir dir("record_stuck");
  RecorderOptions options;
  options.frame_timeout = std::chrono::milliseconds(1);
  options.max_consecutive_timeouts = 3;
  StuckCamera stuck(-1);
  auto timed_out = record_camera(stuck, dir.path() / "a", 10, {}, options);
  ASSERT_FALSE(timed_out);
  EXPECT_TRUE(contains(timed_out.error().message, "delivered no frame"))
      << timed_out.error().message;
  EXPECT_FALSE(stuck.started_);  // stopped on the error path too

  StuckCamera failing(2);
  auto failed = record_camera(failing, dir.path() / "b", 10, {}, options);
  ASSERT_FALSE(failed);
  EXPECT_TRUE(contains(failed.error().message, "device unplugged"));
  EXPECT_TRUE(contains(failed.error().message, "2 frames recorded so far"));
  auto reader = FakenectDumpReader::open(dir.path() / "b");
  ASSERT_TRUE(reader) << reader.error().message;
  EXPECT_EQ(reader->depth_frame_count(), 2u);
}

}  // namespace
}  // namespace fb
