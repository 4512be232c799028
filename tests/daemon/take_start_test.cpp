// The take's start beside the frame loop (TakeStart) and the frames held meanwhile
// (FusionBacklog): the loop never waits for the detection, every attempt runs on the frame it
// was offered, and held frames come back in order.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <future>
#include <thread>

#include "firmware/daemon/fusion_backlog.hpp"
#include "firmware/daemon/take_start.hpp"

namespace fb {
namespace {

RgbdFrame frame_numbered(std::uint64_t index) {
  RgbdFrame f;
  f.index = index;
  f.color.resize(4, 2);
  f.color.at(0, 0) = Rgb8{static_cast<std::uint8_t>(index), 0, 0};
  f.depth_mm.resize(4, 2);
  f.depth_mm.at(1, 1) = static_cast<std::uint16_t>(500 + index);
  return f;
}

// Polls until decided; the deadline only guards against a hang.
bool poll_until_decided(TakeStart& start) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (!start.poll()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return true;
}

TEST(TakeStart, RunsBesideTheLoopOnTheFrameItWasOffered) {
  std::promise<void> release;
  std::shared_future<void> released = release.get_future().share();
  std::atomic<int> calls{0};
  TakeStart start(
      [&](const ColorImage& color, const DepthImage& depth,
          std::uint64_t index) -> Result<StartedTake> {
        ++calls;
        released.wait();
        StartedTake s;
        s.frame_index = index;
        s.box.rect = PixelRect::from_size(0, 0, static_cast<int>(color.at(0, 0).r) + 16,
                                          static_cast<int>(depth.at(1, 1)));
        return s;
      },
      "no detector");
  start.offer(frame_numbered(0));
  // Offers while the attempt runs neither block nor start another attempt.
  for (std::uint64_t i = 1; i < 5; ++i) {
    start.offer(frame_numbered(i));
    EXPECT_FALSE(start.poll());
  }
  release.set_value();
  ASSERT_TRUE(poll_until_decided(start));
  EXPECT_EQ(calls.load(), 1);
  ASSERT_TRUE(start.started().has_value());
  EXPECT_EQ(start.started()->frame_index, 0u);
  EXPECT_EQ(start.started()->box.rect.width(), 16);    // frame 0's colour
  EXPECT_EQ(start.started()->box.rect.height(), 500);  // frame 0's depth
  const ColorImage color = start.release_start_color();
  ASSERT_EQ(color.width, 4);
  EXPECT_EQ(color.at(0, 0).r, 0);
}

TEST(TakeStart, RetriesOnLaterFramesThenGivesUpWithTheReason) {
  std::atomic<int> calls{0};
  std::vector<std::uint64_t> tried;
  std::mutex tried_mutex;
  TakeStart start(
      [&](const ColorImage&, const DepthImage&, std::uint64_t index) -> Result<StartedTake> {
        ++calls;
        std::lock_guard lock(tried_mutex);
        tried.push_back(index);
        return fail("no face in frame " + std::to_string(index));
      },
      "no detector", /*max_attempts=*/3);
  std::uint64_t index = 0;
  while (!start.poll() && index < 1000) {
    start.offer(frame_numbered(index++));
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  EXPECT_TRUE(start.poll());
  EXPECT_FALSE(start.started().has_value());
  EXPECT_EQ(calls.load(), 3);
  std::lock_guard lock(tried_mutex);
  ASSERT_EQ(tried.size(), 3u);
  EXPECT_LT(tried[0], tried[1]);
  EXPECT_LT(tried[1], tried[2]);
  EXPECT_EQ(start.note(), "no face in frame " + std::to_string(tried[2]));
}

TEST(TakeStart, WithoutADetectorIsDecidedAtOnceAndSaysWhy) {
  TakeStart start({}, "no landmark detector (off)");
  EXPECT_TRUE(start.poll());
  start.offer(frame_numbered(0));
  EXPECT_FALSE(start.started().has_value());
  EXPECT_EQ(start.note(), "no landmark detector (off)");
}

TEST(TakeStart, WaitAndDestructionLetARunningAttemptFinish) {
  std::atomic<bool> finished{false};
  auto slow = [&](const ColorImage&, const DepthImage&,
                  std::uint64_t index) -> Result<StartedTake> {
    std::this_thread::sleep_for(std::chrono::milliseconds(30));
    finished = true;
    StartedTake s;
    s.frame_index = index;
    return s;
  };
  {
    TakeStart start(slow, "");
    start.offer(frame_numbered(7));
    start.wait();
    ASSERT_TRUE(start.started().has_value());
    EXPECT_EQ(start.started()->frame_index, 7u);
  }
  finished = false;
  {
    TakeStart start(slow, "");
    start.offer(frame_numbered(8));
  }  // the attempt reads the object's copies: destruction waits for it
  EXPECT_TRUE(finished.load());
}

TEST(FusionBacklog, HoldsInOrderTurnsAwayWhenFullAndDropsThroughAFrame) {
  FusionBacklog backlog(3);
  for (std::uint64_t i = 0; i < 5; ++i) backlog.push(frame_numbered(i));
  EXPECT_EQ(backlog.size(), 3u);
  EXPECT_EQ(backlog.turned_away(), 2);
  EXPECT_EQ(backlog.front_index(), 0u);
  EXPECT_EQ(backlog.front_depth().at(1, 1), 500);
  // Frame 1 was fused elsewhere: frame 0 before it is let go unfused, frame 2 stays.
  EXPECT_EQ(backlog.drop_through(1), 1);
  ASSERT_EQ(backlog.size(), 1u);
  EXPECT_EQ(backlog.front_index(), 2u);
  EXPECT_EQ(backlog.front_depth().at(1, 1), 502);
  // Slots are reused around the ring.
  backlog.push(frame_numbered(9));
  backlog.push(frame_numbered(10));
  backlog.pop();
  EXPECT_EQ(backlog.front_index(), 9u);
  backlog.pop();
  EXPECT_EQ(backlog.front_depth().at(1, 1), 510);
  backlog.pop();
  EXPECT_TRUE(backlog.empty());
  // Memory given back once caught up; the backlog still holds frames after it.
  backlog.release();
  backlog.push(frame_numbered(11));
  EXPECT_EQ(backlog.front_depth().at(1, 1), 511);
}

}  // namespace
}  // namespace fb
