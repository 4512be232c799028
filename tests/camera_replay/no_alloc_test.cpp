// Steady-state per-frame code allocates nothing: replay next_frame() (reading PGM/PPM files,
// converting to millimetres) and FakenectRecorder::write() (encoding and writing files, appending
// INDEX.txt). A separate binary because it interposes malloc for the whole process.
#include <atomic>
#include <cstdlib>

#include <gtest/gtest.h>

#include "drivers/camera/recorder/recorder.hpp"
#include "drivers/camera/replay/replay_camera.hpp"
#include "tests/camera_replay/test_dumps.hpp"
#include "tests/common/allocation_counter.hpp"

namespace fb {
namespace {

using test::CountAllocations;

// Plays `camera` once to size every buffer, then counts allocations over a second full pass.
long replay_allocations(DepthCamera& camera, int& frames) {
  RgbdFrame frame;
  EXPECT_TRUE(camera.start());
  while (*camera.next_frame(frame, std::chrono::milliseconds(0)) == FrameStatus::kFrame) {
  }
  EXPECT_TRUE(camera.start());
  frames = 0;
  long allocations = 0;
  {
    CountAllocations counter;
    for (;;) {
      auto status = camera.next_frame(frame, std::chrono::milliseconds(0));
      if (!status.ok() || *status != FrameStatus::kFrame) break;
      ++frames;
    }
    allocations = counter.count();
  }
  return allocations;
}

TEST(NoAllocation, ReplayAndRecordSteadyState) {
  if (!test::allocation_counting_available()) {
    GTEST_SKIP() << "allocation counting needs glibc without sanitizers";
  }
  test::TempDir dir("noalloc");
  {
    auto w = FakenectDumpWriter::create(dir.path() / "src", KinectCalibration::defaults());
    ASSERT_TRUE(w);
    for (int i = 0; i < 8; ++i) {
      if (i % 2 == 0) {
        ASSERT_TRUE(w->write_color(test::test_color(i), 1.0 + i * 0.033, i));
      }
      ASSERT_TRUE(w->write_depth(test::test_disparity(i), 1.01 + i * 0.033, i));
    }
  }
  auto cam = open_replay_camera(dir.path() / "src");
  ASSERT_TRUE(cam) << cam.error().message;
  int frames = 0;
  EXPECT_EQ(replay_allocations(**cam, frames), 0);
  EXPECT_EQ(frames, 8);

  // Recorder: the first frame sizes the buffers, the rest must not allocate.
  auto rec = FakenectRecorder::create(dir.path() / "out", (*cam)->info());
  ASSERT_TRUE(rec) << rec.error().message;
  RgbdFrame frame;
  ASSERT_TRUE((*cam)->start());
  ASSERT_EQ(*(*cam)->next_frame(frame, std::chrono::milliseconds(0)), FrameStatus::kFrame);
  ASSERT_TRUE(rec->write(frame));
  long allocations = 0;
  int written = 1;
  {
    CountAllocations counter;
    while (*(*cam)->next_frame(frame, std::chrono::milliseconds(0)) == FrameStatus::kFrame) {
      if (!rec->write(frame).ok()) break;
      ++written;
    }
    allocations = counter.count();
  }
  EXPECT_EQ(written, 8);
  EXPECT_EQ(allocations, 0);
  ASSERT_TRUE(rec->finish());
}

TEST(NoAllocation, RealDumpReplay) {
  if (!test::allocation_counting_available()) {
    GTEST_SKIP() << "allocation counting needs glibc without sanitizers";
  }
  std::string why;
  const auto source = test::real_dump_dir(why);
  if (source.empty()) GTEST_SKIP() << why;
  auto cam = open_replay_camera(source);
  ASSERT_TRUE(cam) << cam.error().message;
  int frames = 0;
  EXPECT_EQ(replay_allocations(**cam, frames), 0);
  EXPECT_EQ(frames, 90);
}

}  // namespace
}  // namespace fb
