// A take's fusion as its frame loop drives it: the start beside the loop (TakeStart: the face
// box, fusion set up on its frame), the frames held meanwhile and while fusion catches up
// (FusionBacklog), fusion from the backlog within a time budget per frame, and the tally for
// the take's quality report. The loop only reads, spools and hands frames over; nothing here
// makes it wait longer than the budget.
#pragma once

#include <chrono>
#include <string>

#include "algo/core/camera_model.hpp"
#include "algo/fusion/face_fusion.hpp"
#include "algo/fusion/view_consistency.hpp"
#include "algo/landmarks/face_region_box.hpp"
#include "drivers/camera/depth_camera.hpp"
#include "firmware/daemon/fusion_backlog.hpp"
#include "firmware/daemon/take_start.hpp"

namespace fb {

// What a take's frame loop counted, for its quality report.
struct TakeTally {
  int recorded = 0, fused = 0;
  int fusion_dropped = 0;  // frames fusion could not follow (lost), kept out
  int not_held = 0;        // frames that arrived while the take started, past the hold
  long long missed = 0;    // frames the sensor overwrote because the loop read them too late
  double rms_sum = 0;
  RigidPose frontal_pose;
  bool box_detected = false;
  std::string box_note;  // why dlib found no face
};

// The take's face detector (the daemon's, shared), or none.
struct TakeDetector {
  LandmarkDetector* detector = nullptr;
  const FaceProportions* proportions = nullptr;
  std::string missing_note;  // why there is none
};

class TakeFusion {
 public:
  using Clock = std::chrono::steady_clock;
  static constexpr std::size_t kBacklogFrames = 12;  // 0.4 s of depth, 7 MB
  // Fusion runs from the backlog until this long after the frame arrived, leaving the rest of
  // the sensor period for reading, spooling and the preview.
  static constexpr double kFuseBudgetMs = 25.0;

  // `fusion` and `consistency` are the daemon's (reused between takes); the take owns them
  // until finish().
  TakeFusion(FaceFusion& fusion, ViewConsistency& consistency, const CameraInfo& info,
             TakeDetector detector, TakeTally& tally);

  // A frame the loop read at `arrived`.
  Result<void> add(const RgbdFrame& frame, Clock::time_point arrived);
  // The take ended: waits for a start still running and fuses what is held.
  Result<void> finish();

  const FaceBox& box() const { return fusion_ready_ ? fusion_.face_box() : box_; }
  // The frontal frame's colour (the first fused frame's), for the landmarks.
  ColorImage& frontal_color() { return frontal_color_; }

 private:
  FrameReport integrate(const DepthImage& depth, const RigidPose* frontal);
  Result<void> start_fusion(const FaceBox& box);
  void count(const FrameReport& report);
  void fuse(const DepthImage& depth);
  void fuse_backlog(Clock::time_point arrived, double budget_ms);
  Result<void> take_over();

  FaceFusion& fusion_;
  ViewConsistency& consistency_;
  const CameraInfo& info_;
  TakeDetector detector_;
  TakeTally& tally_;
  KinectRegistration registration_;
  TakeStart start_;
  FusionBacklog backlog_{kBacklogFrames};
  bool fusion_ready_ = false;
  FaceBox box_;
  ColorImage frontal_color_;
};

}  // namespace fb
