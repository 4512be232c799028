// The synthetic camera's real-time delivery (sim/camera/render_ahead.hpp): frames arrive on the
// sensor's clock, a late reader loses frames as it would with a real Kinect, the frames are the
// same as rendered on demand, and injected stalls and failures behave like a stalled or
// unplugged sensor. Nothing here asserts a time: only what was delivered.
#include "sim/camera/render_ahead.hpp"

#include <chrono>
#include <cstring>
#include <thread>

#include <gtest/gtest.h>

#include "sim/camera/synthetic_camera.hpp"
#include "tests/common/test_face_model.hpp"

namespace fb {
namespace {

using std::chrono::milliseconds;

// A stand-in renderer: frame i's depth is filled with i, so a delivered frame shows which
// frame it is.
RenderAhead::RenderFn counting_renderer(int sleep_ms) {
  return [sleep_ms](std::uint64_t i, RgbdFrame& frame, FrameTruth& truth) -> Result<void> {
    if (sleep_ms > 0) std::this_thread::sleep_for(milliseconds(sleep_ms));
    frame.index = i;
    frame.depth_mm.resize(4, 4);
    std::fill(frame.depth_mm.pixels.begin(), frame.depth_mm.pixels.end(),
              static_cast<std::uint16_t>(i));
    truth.face_hidden_fraction = static_cast<double>(i);
    return success();
  };
}

TEST(RenderAhead, AReaderThatKeepsUpGetsEveryFrameInOrder) {
  RenderAheadOptions o;
  o.frame_count = 20;
  o.fps = 200.0;
  auto ahead = RenderAhead::start(o, counting_renderer(0));
  ASSERT_TRUE(ahead) << ahead.error().message;
  RgbdFrame frame;
  FrameTruth truth;
  std::vector<std::uint64_t> got;
  while (true) {
    auto s = (*ahead)->next(frame, truth, milliseconds(2000));
    ASSERT_TRUE(s);
    if (*s == FrameStatus::kEndOfStream) break;
    if (*s == FrameStatus::kTimeout) continue;
    EXPECT_EQ(frame.depth_mm.pixels[0], frame.index);
    EXPECT_EQ(truth.face_hidden_fraction, static_cast<double>(frame.index));
    got.push_back(frame.index);
  }
  const auto stats = (*ahead)->stats();
  // Whatever the machine's speed: every frame is either delivered or counted as overwritten.
  EXPECT_EQ(static_cast<long long>(got.size()) + stats.overwritten, 20);
  EXPECT_EQ(stats.delivered, static_cast<long long>(got.size()));
  for (std::size_t i = 1; i < got.size(); ++i) EXPECT_GT(got[i], got[i - 1]);
  EXPECT_EQ(got.back(), 19u);
}

TEST(RenderAhead, AReaderThatSleepsLosesTheOverwrittenFrames) {
  RenderAheadOptions o;
  o.frame_count = 12;
  o.fps = 100.0;  // 10 ms a frame; the reader sleeps 60 ms before its first read
  auto ahead = RenderAhead::start(o, counting_renderer(0));
  ASSERT_TRUE(ahead);
  std::this_thread::sleep_for(milliseconds(60));
  RgbdFrame frame;
  FrameTruth truth;
  auto s = (*ahead)->next(frame, truth, milliseconds(2000));
  ASSERT_TRUE(s);
  ASSERT_EQ(*s, FrameStatus::kFrame);
  // A sensor keeps only the newest frame (queue_frames 1): the first read is not frame 0, and
  // the frames before it are counted as overwritten, leaving the gap in the index.
  EXPECT_GT(frame.index, 0u);
  EXPECT_EQ((*ahead)->stats().overwritten, static_cast<long long>(frame.index));
}

TEST(RenderAhead, ARenderErrorReachesTheReader) {
  RenderAheadOptions o;
  o.frame_count = 5;
  auto ahead =
      RenderAhead::start(o, [](std::uint64_t i, RgbdFrame& f, FrameTruth&) -> Result<void> {
        if (i == 2) return fail("renderer broke at frame 2");
        f.index = i;
        return success();
      });
  ASSERT_TRUE(ahead);
  RgbdFrame frame;
  FrameTruth truth;
  Error error;
  for (int i = 0; i < 100; ++i) {
    auto s = (*ahead)->next(frame, truth, milliseconds(100));
    if (!s) {
      error = s.error();
      break;
    }
  }
  EXPECT_EQ(error.message, "renderer broke at frame 2");
}

TEST(RenderAhead, BadOptionsAreClearErrors) {
  RenderAheadOptions o;
  o.frame_count = 0;
  auto a = RenderAhead::start(o, counting_renderer(0));
  ASSERT_FALSE(a);
  EXPECT_NE(a.error().message.find("at least one frame"), std::string::npos);
  o.frame_count = 3;
  o.max_slots = 1;
  EXPECT_FALSE(RenderAhead::start(o, counting_renderer(0)));
}

std::unique_ptr<SyntheticCamera> started_camera(const std::string& uri_arguments) {
  auto options = parse_synthetic_options(uri_arguments, test::face_model());
  EXPECT_TRUE(options) << (options ? "" : options.error().message);
  if (!options) return nullptr;
  auto camera = make_synthetic_camera(test::face_model(), *options);
  EXPECT_TRUE(camera);
  if (!camera) return nullptr;
  EXPECT_TRUE((*camera)->start());
  return std::move(*camera);
}

// The real-time camera renders the same frames as the on-demand one, frame for frame.
TEST(SyntheticRealtime, DeliversTheSameFramesAsOnDemand) {
  auto on_demand = started_camera("seed=5,frames=6");
  auto realtime = started_camera("seed=5,frames=6,realtime=1");
  ASSERT_TRUE(on_demand && realtime);
  std::vector<RgbdFrame> reference(6);
  std::vector<Eigen::Vector2d> reference_landmark(6);
  for (int i = 0; i < 6; ++i) {
    auto s = on_demand->next_frame(reference[i], milliseconds(0));
    ASSERT_TRUE(s && *s == FrameStatus::kFrame);
    reference_landmark[i] = on_demand->truth()->landmarks_color_px[30];
  }
  RgbdFrame frame;
  int compared = 0;
  while (true) {
    auto s = realtime->next_frame(frame, milliseconds(3000));
    ASSERT_TRUE(s) << s.error().message;
    if (*s == FrameStatus::kEndOfStream) break;
    if (*s == FrameStatus::kTimeout) continue;
    const RgbdFrame& r = reference[frame.index];
    EXPECT_EQ(frame.depth_mm.pixels, r.depth_mm.pixels) << "frame " << frame.index;
    EXPECT_EQ(frame.raw_disparity.pixels, r.raw_disparity.pixels) << "frame " << frame.index;
    EXPECT_EQ(std::memcmp(frame.color.pixels.data(), r.color.pixels.data(),
                          r.color.pixels.size() * sizeof(Rgb8)),
              0)
        << "frame " << frame.index;
    EXPECT_EQ(frame.depth_device_timestamp, r.depth_device_timestamp);
    ASSERT_NE(realtime->truth(), nullptr);
    EXPECT_EQ(realtime->truth()->landmarks_color_px[30], reference_landmark[frame.index]);
    EXPECT_FALSE(realtime->truth()->identity_coeffs.empty());
    ++compared;
  }
  const auto stats = realtime->realtime_stats();
  ASSERT_TRUE(stats);
  EXPECT_EQ(compared + stats->overwritten, 6);
  EXPECT_GE(compared, 1);
}

TEST(SyntheticFaults, StallAndFailAfterNFrames) {
  for (const char* fault : {"stall_after=2", "fail_after=2"}) {
    auto camera = started_camera(std::string("seed=1,frames=10,") + fault);
    ASSERT_TRUE(camera);
    RgbdFrame frame;
    for (int i = 0; i < 2; ++i) {
      auto s = camera->next_frame(frame, milliseconds(10));
      ASSERT_TRUE(s && *s == FrameStatus::kFrame) << fault;
    }
    auto s = camera->next_frame(frame, milliseconds(10));
    if (std::string(fault).rfind("stall", 0) == 0) {
      ASSERT_TRUE(s);
      EXPECT_EQ(*s, FrameStatus::kTimeout);
    } else {
      ASSERT_FALSE(s);
      EXPECT_NE(s.error().message.find("failed after 2 frames"), std::string::npos);
    }
  }
  auto bad = parse_synthetic_options("fail_after=1.5", test::face_model());
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().message.find("fail_after"), std::string::npos);
}

}  // namespace
}  // namespace fb
