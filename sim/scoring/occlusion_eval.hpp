// eval track's figures for occlusion as data and acquisition among clutter (issue 35, items 4
// and 5), scored against the realistic world's truth (FrameTruth::face_hidden_fraction, the
// true pose): whether the tracker reports a hand that hides the face, never a clear face, how
// soon it says the face is clear again, and whether it finds the face when a hand, the desk or
// the chest is nearer to the camera than the face.
#pragma once

#include <nlohmann/json.hpp>
#include <vector>

#include "sim/subject/synthetic_take.hpp"
#include "sim/scoring/take_runner.hpp"

namespace fb::cli {

// Truth hidden share at or over which the face must be reported occluded, and under which a
// report is false (between the two the hand is arriving or leaving: counted, not scored).
inline constexpr double kOcclusionMustReport = 0.3;
inline constexpr double kOcclusionClear = 0.1;

class OcclusionScore {
 public:
  // One run of the tracker over `take` (frames after calibration are scored).
  void add(const RenderedTake& take, const std::vector<FrameResult>& results);
  // occlusion_reported_fraction (null without a frame hidden >= 30 %), occlusion_false_reports,
  // occlusion_recovery_frames (worst take; null without a hand leaving the face, -1 = never),
  // and the frame counts behind them.
  nlohmann::json json() const;

 private:
  int hidden_frames_ = 0, reported_ = 0;
  int clear_frames_ = 0, false_reports_ = 0;
  int partial_frames_ = 0, partial_reported_ = 0;
  int leaves_ = 0, recovery_ = 0;  // hand-leaving events, the worst recovery (-1 = never)
  float least_hidden_reported_ = 1.0f, most_clear_measured_ = 0.0f;
};

// Whether the take's first frame shows a surface nearer to the camera than the face (its nose
// tip) over at least a few hundred pixels: what fools acquisition by the nearest surface.
bool has_nearer_distractors(const RenderedTake& take);

class AcquisitionScore {
 public:
  // A run over a take with nearer distractors counts as acquired when the tracker calibrated
  // and, on its tracked frames after that, sat on the face: median rotation error under
  // 10 deg and face-centre error under 25 mm (a lock on a hand or the desk is far off both).
  void add(const RenderedTake& take, const std::vector<FrameResult>& results);
  // acquired_with_nearer_distractors: the share of such runs (null when no take had them).
  nlohmann::json json() const;

 private:
  int runs_ = 0, acquired_ = 0;
};

// What the fields above mean, for the JSON's "setup".
nlohmann::json occlusion_setup_notes();

}  // namespace fb::cli
