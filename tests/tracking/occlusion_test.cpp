// Occlusion as data (issue 35, item 4): the tracker reports a hand in front of the face
// (TrackReport::occluded, occluded_fraction), never a clear face, and says it is clear again
// once the hand has gone. Scored against the synthetic world's truth (the share of the face's
// pixels a hand covers, FrameTruth::face_hidden_fraction).
#include <algorithm>
#include <cstdio>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "algo/tracking/face_tracker.hpp"
#include "algo/tracking/occlusion_report.hpp"
#include "sim/camera/synthetic_camera.hpp"
#include "tests/common/synthetic_take.hpp"
#include "tests/common/test_face_model.hpp"

namespace fb {
namespace {

using Take = test::RenderedTake;
using test::render;

struct OcclusionRun {
  int covered = 0, covered_reported = 0;  // frames hidden >= 30 %
  int clear = 0, clear_reported = 0;      // frames hidden < 10 %
  float least_covered_fraction = 1.0f, most_clear_fraction = 0.0f;
  int recovery = -1;  // frames from the hand leaving the face to "clear" reported
};

// Landmarks: truth + 1.5 px noise (all frames, or only while searching and calibrating).
OcclusionRun track_hand_pass(const Take& take, bool with_landmarks) {
  OcclusionRun run;
  auto tracker = FaceTracker::create(test::face_model(), take.intrinsics);
  EXPECT_TRUE(tracker.ok()) << tracker.error().message;
  if (!tracker) return run;
  TrackReport report;
  std::mt19937 rng(3);
  std::normal_distribution<float> noise(0.0f, 1.5f);
  std::vector<Eigen::Vector2f> points(68);
  int left = -1;  // the first frame after the pass with the hand off the face
  bool found = false;
  for (std::size_t f = 0; f < take.depth.size(); ++f) {
    const FrameTruth& t = take.truth[f];
    for (int l = 0; l < 68; ++l)
      points[l] = t.landmarks_depth_px[l].cast<float>() + Eigen::Vector2f(noise(rng), noise(rng));
    TrackLandmarks landmarks{points, {}};
    // Depth only: landmarks only while there is no face or the identity calibrates, as the
    // device and `track` use their detector.
    const bool detect = with_landmarks || !found || !(*tracker)->calibrated();
    (*tracker)->track(take.depth[f], f / 30.0, detect ? &landmarks : nullptr, report);
    // Scored from the first frame with the face (calibrating or not: the mask is made for
    // the pose either way).
    found = found || report.face_found;
    if (!found) continue;
    const double hidden = t.face_hidden_fraction;
    if (hidden >= 0.3) {
      ++run.covered;
      run.covered_reported += report.occluded ? 1 : 0;
      run.least_covered_fraction = std::min(run.least_covered_fraction, report.occluded_fraction);
    } else if (hidden < 0.1) {
      ++run.clear;
      run.clear_reported += report.occluded ? 1 : 0;
      run.most_clear_fraction = std::max(run.most_clear_fraction, report.occluded_fraction);
    }
    if (f > 0 && take.truth[f - 1].face_hidden_fraction > 0.0 && hidden == 0.0 && left < 0)
      left = static_cast<int>(f);
    if (left >= 0 && run.recovery < 0 && report.face_found && !report.occluded)
      run.recovery = static_cast<int>(f) - left;
  }
  return run;
}

// A hand sweeps across in front of the face (130 mm nearer) while another rests beside it
// (its rim is within the mask's reach of the face's edge): the frames the hand hides 30 % or
// more of the face are reported occluded, the clear ones are not, and "clear" is reported
// within 2 frames of the hand leaving the face. With landmarks and depth only (landmarks to
// find the face and calibrate).
TEST(Tracker, ReportsOcclusionWhileAHandCoversTheFace) {
  SyntheticOptions o;
  o.seed = 7;
  o.frame_count = 70;
  o.yaw_amplitude_deg = 10.0;
  o.pitch_amplitude_deg = 5.0;
  o.world.seed = 7;
  o.world.side_hand = true;
  o.world.hand_pass = true;
  o.world.hand_pass_start = 34;
  o.world.hand_pass_frames = 30;
  const Take take = render(o);
  ASSERT_EQ(take.depth.size(), 70u);
  for (const bool with_landmarks : {true, false}) {
    const OcclusionRun r = track_hand_pass(take, with_landmarks);
    std::fprintf(stderr,
                 "%s: covered %d/%d reported (least fraction %.2f), clear %d/%d reported "
                 "(most fraction %.2f), recovery %d\n",
                 with_landmarks ? "landmarks" : "depth only", r.covered_reported, r.covered,
                 r.least_covered_fraction, r.clear_reported, r.clear, r.most_clear_fraction,
                 r.recovery);
    ASSERT_GE(r.covered, 4) << "the pass must cover the face on a few frames";
    ASSERT_GE(r.clear, 15);
    EXPECT_EQ(r.covered_reported, r.covered);
    EXPECT_EQ(r.clear_reported, 0);
    EXPECT_GE(r.recovery, 0);
    EXPECT_LE(r.recovery, 2);
  }
}

// What a consumer (`track`, the device) reports: the frames occluded and one message per
// change, not one per frame.
TEST(OcclusionLog, CountsFramesAndReportsEachChangeOnce) {
  OcclusionLog log;
  std::vector<OcclusionLog::Change> changes;
  for (const bool occluded : {false, true, true, true, false, false, true, false})
    changes.push_back(log.add(occluded));
  using C = OcclusionLog::Change;
  EXPECT_EQ(changes, (std::vector<C>{C::kNone, C::kOccluded, C::kNone, C::kNone, C::kClear,
                                     C::kNone, C::kOccluded, C::kClear}));
  EXPECT_EQ(log.occluded_frames(), 4);
  EXPECT_NEAR(hidden_fraction(30, 70), 0.3f, 1e-6f);
  EXPECT_EQ(hidden_fraction(0, 0), 0.0f);
}

}  // namespace
}  // namespace fb
