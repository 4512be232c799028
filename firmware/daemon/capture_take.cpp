// The capture take: one guide expression recorded and fused frame by frame on the worker
// thread, then its quality report.
#include <malloc.h>

#include <cstdio>

#include "algo/core/clock.hpp"
#include "drivers/camera/common/device_json.hpp"
#include "firmware/daemon/daemon_impl.hpp"
#include "firmware/daemon/take_fusion.hpp"

namespace fb {

// The camera for a take: a synthetic subject making the guide expression (a camera that takes
// an expression control, a module from sim/), opened for the take with the guide's
// expression, a head turn and the take's length; null when the preview camera records.
Result<std::unique_ptr<DepthCamera>> Daemon::Impl::open_take_camera(int index, int frames) {
  if (!config.camera.synthetic_imitates_guide ||
      !camera_has_control(config.camera.uri, kControlExpression))
    return std::unique_ptr<DepthCamera>();
  CameraControls controls = {{std::string(kControlExpression), guide[index].synthetic_expr},
                             {std::string(kControlMotion), "headturn"},
                             {std::string(kControlFrames), std::to_string(frames)}};
  // A real sensor delivers on its own clock and overwrites what the loop is too late for;
  // the rendering camera does the same when asked (it renders ahead on its own thread).
  if (config.camera.realtime && camera_has_control(config.camera.uri, kControlRealtime))
    controls.push_back({std::string(kControlRealtime), "1"});
  // Rendered with the face model the fitter already holds (FaceModel is immutable after
  // loading) instead of the module loading another 21 MB copy for every take.
  CameraResources lent;
  if (fitter) lent.face_model = &fitter->model();
  auto opened = open_camera(config.camera.uri, controls, lent);
  if (!opened) return opened.failure();
  // The take renders the same unit as the preview: under the same calibration.
  auto calibrated = with_active_calibration(std::move(*opened));
  if (!calibrated) return calibrated.failure();
  if (auto ok = (*calibrated)->start(); !ok) return ok.failure();
  return std::move(*calibrated);
}

// The first take's start took three times as long as the next ones' (0.4 s: fusion's volume and
// buffers and the detector's are made on first use), longer than the frames it can hold
// meanwhile. Made here once, at start-up, with the preview camera's geometry.
void Daemon::Impl::warm_up_take() {
  const CameraInfo& info = preview_camera->info();
  (void)fusion.reset(info.depth_intrinsics, default_face_box(info.width, info.height));
  (void)consistency.reset(info.depth_intrinsics);
  if (take_detector) {
    ColorImage blank;
    blank.resize(info.width, info.height);
    (void)take_detector->detect(blank);  // finds nothing; sizes the detector's buffers
  }
}

// Records one take and fuses it frame by frame. Returns false when cancelled or stopping (the
// capture stays not done: begin_capture counted the attempt, nothing else is written).
Result<bool> Daemon::Impl::record_take(QaReport& qa, CaptureCommit& commit) {
  std::int64_t session;
  int index;
  {
    std::lock_guard lock(status_mutex);
    session = status.session;
    index = status.capture_index;
  }
  if (index < 0 || index >= static_cast<int>(guide.size()))
    return fail("no capture selected for recording");
  // The peak resident memory (budget 256 MB) is reached while a take is fused. Heap pages freed
  // by the last take's fit and by the HTTP threads stay resident inside glibc's arenas, more of
  // them the more the threads interleave (a slower or busier CPU); hand them back first, so the
  // peak is the take's working set and not that plus the fragmentation (~1 ms).
  malloc_trim(0);
  {
    std::lock_guard lock(records_mutex);
    if (auto ok = records->begin_capture(session, index); !ok) return ok.failure();
  }
  auto spool = FrameSpool::create(config.storage.data_dir / "spool");
  if (!spool) return spool.failure();
  commit.frames = std::move(*spool);
  const int n = config.camera.capture_frames;
  update_status([&](StatusData& s) {
    ++s.attempts;
    s.take_frames = 0;
    s.message = "Recording: turn your head slowly left and right...";
  });
  auto take_camera = open_take_camera(index, n);
  if (!take_camera) return take_camera.failure();
  DepthCamera* camera = *take_camera ? take_camera->get() : preview_camera.get();
  const CameraInfo& info = camera->info();

  TakeTally tally;
  TakeFusion take(
      fusion, consistency, info,
      {take_detector ? &*take_detector : nullptr, take_proportions ? &*take_proportions : nullptr,
       "no landmark detector (" + fitter_error + ")"},
      tally);

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
    watchdog_ping();
    if (stopping || cancel_pending()) {
      std::lock_guard lock(status_mutex);
      status.frames_dropped += tally.missed;
      return false;
    }
    auto got = camera->next_frame(frame, std::chrono::milliseconds(500));
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
    if (tally.recorded % config.camera.stored_frame_stride == 0) {
      if (auto ok = commit.frames->append(frame); !ok) return ok.failure();
    }
    ++tally.recorded;
    if (tally.recorded % 5 == 0 || tally.recorded == n) {
      std::lock_guard lock(preview_mutex);
      make_preview(frame, take.box(), preview);
    }
    update_status([&](StatusData& s) {
      s.take_frames = tally.recorded;
      ++s.frames_total;
    });
  }
  update_status([&](StatusData& s) { s.frames_dropped += tally.missed; });
  if (tally.recorded == 0) return fail("the camera delivered no frames for the take");
  if (auto ok = take.finish(); !ok) return ok.failure();
  pending_view.color = std::move(take.frontal_color());
  assess_take(tally, info, qa, commit);
  return true;
}

// Quality: how much of the face box the fused surface covers, how well frames aligned, and how
// many frames could be fused at all.
void Daemon::Impl::assess_take(const TakeTally& tally, const CameraInfo& info, QaReport& qa,
                               CaptureCommit& commit) {
  SurfaceView view = fusion.render(tally.frontal_pose);
  pending_view.intrinsics = info.depth_intrinsics;
  pending_view.calibration = info.calibration;
  long long covered = 0;
  const FaceBox clipped =
      fusion.box_for(tally.frontal_pose).clipped(view.depth_mm.width, view.depth_mm.height);
  commit.fused_depth.resize(view.depth_mm.width, view.depth_mm.height);
  for (int y = 0; y < view.depth_mm.height; ++y)
    for (int x = 0; x < view.depth_mm.width; ++x) {
      const float z = view.depth_mm.at(x, y);
      commit.fused_depth.at(x, y) = z > 0 && z < 65535 ? static_cast<std::uint16_t>(z + 0.5f) : 0;
      if (z > 0 && clipped.contains(x, y)) ++covered;
    }
  qa.coverage = clipped.empty() ? 0.0
                                : static_cast<double>(covered) /
                                      (static_cast<double>(clipped.width) * clipped.height);
  qa.residual_mm = tally.fused > 0 ? tally.rms_sum / tally.fused : 0.0;
  qa.fused_fraction = static_cast<double>(tally.fused) / tally.recorded;
  const auto& th = config.session;
  if (qa.coverage < th.min_coverage)
    qa.reason = "face coverage " + std::to_string(qa.coverage).substr(0, 4) + " below " +
                std::to_string(th.min_coverage).substr(0, 4);
  else if (qa.fused_fraction < th.min_fused_fraction)
    qa.reason = "only " + std::to_string(tally.fused) + " of " + std::to_string(tally.recorded) +
                " frames could be aligned";
  else if (tally.fused == 0 || qa.residual_mm > th.max_residual_mm)
    qa.reason = "alignment residual " + std::to_string(qa.residual_mm).substr(0, 4) + " mm";
  qa.passed = qa.reason.empty();
  pending_view.depth_mm = std::move(view.depth_mm);
  pending_view.normals = std::move(view.normals);
  consistency.confidence(pending_view.confidence);
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
               clipped.x, clipped.y, clipped.width, clipped.height,
               tally.box_detected ? "from dlib" : "fixed (no face found: ",
               tally.box_detected ? "" : (tally.box_note + ")").c_str());
}

}  // namespace fb
