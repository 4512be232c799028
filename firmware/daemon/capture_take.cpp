#include "firmware/daemon/capture_take.hpp"

#include <malloc.h>

#include <cstdio>

#include "algo/core/clock.hpp"
#include "drivers/camera/common/device_json.hpp"

namespace fb {

void CaptureTake::set_detector(LandmarkDetector detector, FaceProportions proportions) {
  detector_.emplace(std::move(detector));
  proportions_ = std::move(proportions);
}

// The first take's start took three times as long as the next ones' (0.4 s: fusion's volume and
// buffers and the detector's are made on first use), longer than the frames it can hold
// meanwhile. Made here once, at start-up, with the preview camera's geometry.
void CaptureTake::warm_up(const CameraInfo& info) {
  (void)fusion_.reset(info.depth_intrinsics, default_face_box(info.width, info.height));
  (void)consistency_.reset(info.depth_intrinsics);
  if (detector_) {
    ColorImage blank;
    blank.resize(info.width, info.height);
    (void)detector_->detect(blank);  // finds nothing; sizes the detector's buffers
  }
}

Result<void> CaptureTake::start(const TakeSettings& settings) {
  settings_ = settings;
  result_ = {};
  // The peak resident memory (budget 256 MB) is reached while a take is fused. Heap pages freed
  // by the last take's fit and by the HTTP threads stay resident inside glibc's arenas, more of
  // them the more the threads interleave (a slower or busier CPU); hand them back first, so the
  // peak is the take's working set and not that plus the fragmentation (~1 ms).
  malloc_trim(0);
  auto spool = FrameSpool::create(settings_.spool_folder);
  if (!spool) return spool.failure();
  result_.commit.frames = std::move(*spool);
  return success();
}

// Records one take and fuses it frame by frame. Returns false when cancelled or stopping (the
// capture stays not done: begin_capture counted the attempt, nothing else is written).
Result<bool> CaptureTake::record(DepthCamera& camera, const TakeHooks& hooks) {
  const int n = settings_.frames;
  const CameraInfo& info = camera.info();
  TakeTally tally;
  TakeFusion take(fusion_, consistency_, info,
                  {detector_ ? &*detector_ : nullptr, proportions_ ? &*proportions_ : nullptr,
                   settings_.no_detector_note},
                  tally);
  CaptureCommit& commit = result_.commit;

  // Frames the camera overwrote because this loop was late: gaps in the stream's index, as
  // the freenect backend's double buffer and the realtime synthetic camera leave them.
  std::uint64_t expected_index = 0;
  // A sensor that stops delivering (cable, power, a stalled USB stream) ends the take with an
  // error instead of a take that never finishes: 3 s without a frame mid-take, 10 s for the
  // first (a stream starting up; a rendering camera renders ahead before its first frame).
  constexpr long long kStallMs = 3000, kFirstFrameMs = 10000;
  auto last_frame_at = Clock::now();
  RgbdFrame frame;
  while (tally.recorded < n) {
    if (hooks.cancelled()) {
      hooks.ended(tally.missed);
      return false;
    }
    auto got = camera.next_frame(frame, std::chrono::milliseconds(500));
    if (!got)
      return fail("the camera failed after " + std::to_string(tally.recorded) +
                  " frames of the take (" + got.error().message +
                  "); check its cable and power, then retry the capture");
    if (*got == FrameStatus::kEndOfStream) break;
    if (*got == FrameStatus::kTimeout) {
      const long long allowed = tally.recorded == 0 ? kFirstFrameMs : kStallMs;
      if (ms_since(last_frame_at) > static_cast<double>(allowed))
        return fail("the camera stopped delivering frames after " + std::to_string(tally.recorded) +
                    " frames of the take (none for " + std::to_string(allowed / 1000) +
                    " s); check its cable and power, then retry the capture");
      continue;
    }
    last_frame_at = Clock::now();
    if (tally.recorded > 0 && frame.index > expected_index)
      tally.missed += static_cast<long long>(frame.index - expected_index);
    expected_index = frame.index + 1;
    // No live registration check here: the take's own frames are checked after it, on the fit
    // thread (registration_allows_fit), so the check never competes with fusion for the CPU.
    if (auto ok = take.add(frame, last_frame_at); !ok) return ok.failure();
    if (tally.recorded % settings_.stored_frame_stride == 0) {
      if (auto ok = commit.frames->append(frame); !ok) return ok.failure();
    }
    ++tally.recorded;
    if (tally.recorded % 5 == 0 || tally.recorded == n) hooks.show(frame, take.box());
    hooks.recorded(tally.recorded);
  }
  hooks.ended(tally.missed);
  if (tally.recorded == 0) return fail("the camera delivered no frames for the take");
  if (auto ok = take.finish(); !ok) return ok.failure();
  result_.view.color = std::move(take.frontal_color());
  assess(tally, info);
  return true;
}

// Quality: how much of the face box the fused surface covers, how well frames aligned, and how
// many frames could be fused at all.
void CaptureTake::assess(const TakeTally& tally, const CameraInfo& info) {
  QaReport& qa = result_.qa;
  CaptureCommit& commit = result_.commit;
  CaptureView& out = result_.view;
  SurfaceView view = fusion_.render(tally.frontal_pose);
  out.intrinsics = info.depth_intrinsics;
  out.calibration = info.calibration;
  long long covered = 0;
  const PixelRect clipped =
      fusion_.box_for(tally.frontal_pose).rect.clipped(view.depth_mm.width, view.depth_mm.height);
  commit.fused_depth.resize(view.depth_mm.width, view.depth_mm.height);
  for (int y = 0; y < view.depth_mm.height; ++y)
    for (int x = 0; x < view.depth_mm.width; ++x) {
      const float z = view.depth_mm.at(x, y);
      commit.fused_depth.at(x, y) = z > 0 && z < 65535 ? static_cast<std::uint16_t>(z + 0.5f) : 0;
      if (z > 0 && clipped.contains(x, y)) ++covered;
    }
  qa.coverage = clipped.empty() ? 0.0
                                : static_cast<double>(covered) /
                                      (static_cast<double>(clipped.width()) * clipped.height());
  qa.residual_mm = tally.fused > 0 ? tally.rms_sum / tally.fused : 0.0;
  qa.fused_fraction = static_cast<double>(tally.fused) / tally.recorded;
  const TakeSettings& th = settings_;
  if (qa.coverage < th.min_coverage)
    qa.reason = "face coverage " + std::to_string(qa.coverage).substr(0, 4) + " below " +
                std::to_string(th.min_coverage).substr(0, 4);
  else if (qa.fused_fraction < th.min_fused_fraction)
    qa.reason = "only " + std::to_string(tally.fused) + " of " + std::to_string(tally.recorded) +
                " frames could be aligned";
  else if (tally.fused == 0 || qa.residual_mm > th.max_residual_mm)
    qa.reason = "alignment residual " + std::to_string(qa.residual_mm).substr(0, 4) + " mm";
  qa.passed = qa.reason.empty();
  out.depth_mm = std::move(view.depth_mm);
  out.normals = std::move(view.normals);
  consistency_.confidence(out.confidence);
  commit.calibration_json = to_device_json(info.calibration);
  commit.qa_scores = {{"coverage", qa.coverage},
                      {"residual_mm", qa.residual_mm},
                      {"fused_fraction", qa.fused_fraction},
                      {"frames_recorded", tally.recorded},
                      {"frames_dropped", static_cast<double>(tally.missed)},
                      {"frames_fused", tally.fused},
                      {"frames_fusion_dropped", tally.fusion_dropped},
                      {"frames_not_held", tally.not_held},
                      {"face_box_detected", tally.box_detected ? 1.0 : 0.0}};
  // The take keeps the frames it fused; the log says how many it could not follow and where
  // the face box came from.
  std::fprintf(stderr,
               "faceboothd: take: %d of %d frames fused, %d dropped (fusion could not follow "
               "the face), %d not fused (arrived while looking for the face), %lld missed (read "
               "too late); face box %d,%d %dx%d %s%s\n",
               tally.fused, tally.recorded, tally.fusion_dropped, tally.not_held, tally.missed,
               clipped.x0, clipped.y0, clipped.width(), clipped.height(),
               tally.box_detected ? "from dlib" : "fixed (no face found: ",
               tally.box_detected ? "" : (tally.box_note + ")").c_str());
}

}  // namespace fb
