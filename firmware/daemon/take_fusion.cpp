#include "firmware/daemon/take_fusion.hpp"

#include <limits>

#include "algo/core/clock.hpp"

namespace fb {

TakeFusion::TakeFusion(FaceFusion& fusion, ViewConsistency& consistency, const CameraInfo& info,
                       TakeDetector detector, TakeTally& tally)
    : fusion_(fusion),
      consistency_(consistency),
      info_(info),
      detector_(std::move(detector)),
      tally_(tally),
      registration_(info.calibration),
      start_(detector_.detector
                 ? TakeStart::StartFn([this](const ColorImage& color, const DepthImage& depth,
                                             std::uint64_t frame_index) -> Result<StartedTake> {
                     // On the start's thread: the loop does not touch fusion until poll().
                     auto region = detect_face_region(*detector_.detector, color, depth,
                                                      registration_, *detector_.proportions);
                     if (!region) return region.failure();
                     if (auto ok = start_fusion(region->box); !ok) return ok.failure();
                     return StartedTake{region->box, frame_index, integrate(depth, nullptr)};
                   })
                 : TakeStart::StartFn(),
             detector_.missing_note),
      box_(default_face_box(info.width, info.height)) {}

// One frame into fusion and into the take's depth confidence; `frontal` is the frontal
// frame's pose (null: this is it).
FrameReport TakeFusion::integrate(const DepthImage& depth, const RigidPose* frontal) {
  const FrameReport report = fusion_.process(depth);
  if (report.fused)
    consistency_.add(depth, fusion_.model_view().levels[0].depth,
                     frontal ? relative_pose(*frontal, report.world_from_camera) : RigidPose{},
                     fusion_.face_box().rect);
  return report;
}

Result<void> TakeFusion::start_fusion(const FaceBox& box) {
  if (auto ok = fusion_.reset(info_.depth_intrinsics, box); !ok) return ok;
  return consistency_.reset(info_.depth_intrinsics);
}

void TakeFusion::count(const FrameReport& report) {
  if (!report.fused) {
    ++tally_.fusion_dropped;
    return;
  }
  if (tally_.fused == 0) tally_.frontal_pose = report.world_from_camera;
  ++tally_.fused;
  tally_.rms_sum += report.rms_mm;
}

void TakeFusion::fuse(const DepthImage& depth) {
  count(integrate(depth, tally_.fused > 0 ? &tally_.frontal_pose : nullptr));
}

void TakeFusion::fuse_backlog(Clock::time_point arrived, double budget_ms) {
  while (!backlog_.empty()) {
    fuse(backlog_.front_depth());
    backlog_.pop();
    if (ms_since(arrived) >= budget_ms) break;
  }
}

// Once the start is decided the loop owns fusion again: the start's frame is fused (frames
// held before it, from failed attempts, are let go); without a face, fusion starts on the
// fixed box from the first held frame.
Result<void> TakeFusion::take_over() {
  fusion_ready_ = true;
  if (const auto& started = start_.started()) {
    box_ = started->box;
    frontal_color_ = start_.release_start_color();
    count(started->first_frame);
    tally_.not_held += backlog_.drop_through(started->frame_index);
    return success();
  }
  return start_fusion(box_);
}

Result<void> TakeFusion::add(const RgbdFrame& frame, Clock::time_point arrived) {
  if (tally_.recorded == 0) frontal_color_ = frame.color;
  if (fusion_ready_ && backlog_.empty()) {
    fuse(frame.depth_mm);
    return success();
  }
  backlog_.push(frame);
  if (!fusion_ready_) {
    start_.offer(frame);
    if (start_.poll())
      if (auto ok = take_over(); !ok) return ok;
  }
  if (fusion_ready_ && !backlog_.empty()) {
    fuse_backlog(arrived, kFuseBudgetMs);
    // Caught up: the held frames' memory goes back before the take's peak (256 MB budget).
    if (backlog_.empty()) backlog_.release();
  }
  return success();
}

Result<void> TakeFusion::finish() {
  if (!fusion_ready_) {
    start_.wait();  // the stream ended while the start was still looking
    if (auto ok = take_over(); !ok) return ok;
  }
  if (!backlog_.empty()) fuse_backlog(Clock::now(), std::numeric_limits<double>::infinity());
  tally_.box_detected = start_.started().has_value();
  tally_.box_note = start_.note();
  tally_.not_held += backlog_.turned_away();
  return success();
}

}  // namespace fb
