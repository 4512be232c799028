// The capture take (firmware/daemon/capture_take.hpp) on its own: a synthetic head turn recorded,
// fused, spooled and assessed through the worker's interface (start, record, take_result), and
// a cancelled take; and the live preview's pictures (live_preview.hpp).
#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <vector>

#include "drivers/camera/depth_camera.hpp"
#include "firmware/daemon/capture_take.hpp"
#include "firmware/daemon/live_preview.hpp"

namespace fb {
namespace {

struct HookLog {
  int shown = 0;
  std::vector<int> recorded;
  int ended = 0;
  long long missed = -1;
};

TakeHooks hooks_for(HookLog& log, int cancel_after = -1) {
  TakeHooks h;
  h.cancelled = [&log, cancel_after] {
    return cancel_after >= 0 && static_cast<int>(log.recorded.size()) >= cancel_after;
  };
  h.show = [&log](const RgbdFrame&, const FaceBox&) { ++log.shown; };
  h.recorded = [&log](int n) { log.recorded.push_back(n); };
  h.ended = [&log](long long missed) {
    ++log.ended;
    log.missed = missed;
  };
  return h;
}

class CaptureTakeTest : public ::testing::Test {
 protected:
  void SetUp() override {
    spool_ = std::filesystem::temp_directory_path() /
             ("fb-capture-take-" +
              std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    std::filesystem::remove_all(spool_);
  }
  void TearDown() override { std::filesystem::remove_all(spool_); }
  TakeSettings settings(int frames) const {
    TakeSettings s;
    s.frames = frames;
    s.stored_frame_stride = 3;
    s.spool_folder = spool_;
    s.no_detector_note = "no detector in this test";
    return s;
  }
  std::filesystem::path spool_;
};

TEST_F(CaptureTakeTest, RecordsFusesSpoolsAndAssessesAHeadTurn) {
  auto camera = open_camera("synthetic:seed=4,frames=30");
  ASSERT_TRUE(camera.ok()) << camera.error().message;
  ASSERT_TRUE((*camera)->start().ok());
  CaptureTake take;
  take.warm_up((*camera)->info());
  ASSERT_TRUE(take.start(settings(30)).ok());
  HookLog log;
  auto took = take.record(**camera, hooks_for(log));
  ASSERT_TRUE(took.ok()) << took.error().message;
  EXPECT_TRUE(*took);

  ASSERT_EQ(log.recorded.size(), 30u);
  EXPECT_EQ(log.recorded.back(), 30);
  EXPECT_EQ(log.shown, 6);  // every 5th frame
  EXPECT_EQ(log.ended, 1);
  EXPECT_EQ(log.missed, 0);  // a camera without its own clock never overwrites a frame

  RecordedTake r = take.take_result();
  EXPECT_EQ(r.commit.frame_count(), 10u);  // every 3rd of 30
  EXPECT_EQ(r.commit.qa_scores.at("frames_recorded"), 30.0);
  EXPECT_EQ(r.commit.qa_scores.at("face_box_detected"), 0.0);
  EXPECT_GE(r.qa.fused_fraction, 0.9);  // 30 of 30 on this build
  EXPECT_GT(r.qa.coverage, 0.25);
  EXPECT_GT(r.qa.residual_mm, 0.0);
  EXPECT_LT(r.qa.residual_mm, 2.5);
  EXPECT_EQ(r.qa.passed, r.qa.reason.empty());
  const CameraInfo& info = (*camera)->info();
  EXPECT_EQ(r.view.color.width, info.width);
  EXPECT_EQ(r.view.depth_mm.width, r.commit.fused_depth.width);
  long long surface = 0;
  for (std::uint16_t z : r.commit.fused_depth.pixels) surface += z > 0;
  EXPECT_GT(surface, 5000);
  // The result was moved out: a second call has nothing.
  EXPECT_EQ(take.take_result().commit.frame_count(), 0u);
}

TEST_F(CaptureTakeTest, CancelledTakeEndsWithoutAResult) {
  auto camera = open_camera("synthetic:seed=4,frames=30");
  ASSERT_TRUE(camera.ok()) << camera.error().message;
  ASSERT_TRUE((*camera)->start().ok());
  CaptureTake take;
  ASSERT_TRUE(take.start(settings(30)).ok());
  HookLog log;
  auto took = take.record(**camera, hooks_for(log, 4));
  ASSERT_TRUE(took.ok()) << took.error().message;
  EXPECT_FALSE(*took);
  EXPECT_EQ(log.recorded.size(), 4u);
  EXPECT_EQ(log.ended, 1);
  RecordedTake r = take.take_result();
  EXPECT_EQ(r.commit.frame_count(), 2u);  // frames 0 and 3 were spooled
  EXPECT_TRUE(r.commit.qa_scores.empty());
  EXPECT_FALSE(r.qa.passed);
}

TEST(LivePreview, HalfSizePictureWithTheFaceBoxOutlined) {
  RgbdFrame frame;
  frame.color.resize(64, 48);
  for (auto& p : frame.color.pixels) p = Rgb8{10, 20, 30};
  LivePreview preview;
  EXPECT_TRUE(preview.picture().empty());
  FaceBox box;
  box.rect = PixelRect::from_size(8, 8, 20, 16);
  preview.show(frame, box);
  ColorImage p = preview.picture();
  ASSERT_EQ(p.width, 32);
  ASSERT_EQ(p.height, 24);
  EXPECT_EQ(p.at(4, 4).g, 220);    // the box's corner (8/2)
  EXPECT_EQ(p.at(13, 11).g, 220);  // and the opposite one ((8+20)/2-1, (8+16)/2-1)
  EXPECT_EQ(p.at(8, 8).g, 20);     // inside: the picture
  EXPECT_EQ(p.at(0, 0).g, 20);
  preview.show(frame);  // no box
  EXPECT_EQ(preview.picture().at(4, 4).g, 20);

  EXPECT_EQ(preview.capture_bmp(), "");
  preview.set_capture_bmp("BM-test");
  EXPECT_EQ(preview.capture_bmp(), "BM-test");
}

}  // namespace
}  // namespace fb
