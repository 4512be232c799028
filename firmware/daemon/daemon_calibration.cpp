// faceboothd's camera calibration: the unit's stored calibration at start, the registration
// health check wired into the status, the LED and the session, and self-calibration from the
// live frames (POST /api/camera/self-calibrate, or [camera] self_calibrate = true).
//
// Threads: the worker owns the cameras, so a self-calibration run is a job on the worker (like
// a take, it reads frames in the frame loop's place); the estimate that decides whether a take
// is fitted runs on the fit thread, on the take's own spooled frames.
#include <cmath>
#include <cstdio>
#include <cstring>

#include "algo/core/clock.hpp"
#include "firmware/daemon/daemon_impl.hpp"
#include "firmware/daemon/status_figures.hpp"

namespace fb {
namespace {

// Frames a self-calibration keeps (the estimator's colour gradients are ~1.2 MB a frame; more
// frames than this are subsampled by it), within the daemon's memory budget.
constexpr int kCalibrationKeptFrames = 24;

// True when `c` is the built-in default calibration (nothing better was known for the unit).
bool is_default_calibration(const KinectCalibration& c) {
  const KinectCalibration d = KinectCalibration::defaults();
  return std::memcmp(&c.reg_info, &d.reg_info, sizeof d.reg_info) == 0 &&
         c.zero_plane_info.dcmos_emitter_distance == d.zero_plane_info.dcmos_emitter_distance &&
         c.zero_plane_info.dcmos_rcmos_distance == d.zero_plane_info.dcmos_rcmos_distance &&
         c.zero_plane_info.reference_distance == d.zero_plane_info.reference_distance &&
         c.zero_plane_info.reference_pixel_size == d.zero_plane_info.reference_pixel_size &&
         c.const_shift == d.const_shift && c.correction.is_identity();
}

nlohmann::json correction_json(const RegistrationCorrection& c) {
  return {{"dx_px", finite_or_zero(c.dx_px)},
          {"dy_px", finite_or_zero(c.dy_px)},
          {"rotation_deg", finite_or_zero(c.rotation_deg)},
          {"depth_scale", finite_or_zero(c.depth_scale)}};
}

}  // namespace

nlohmann::json registration_json(const StatusData& s) {
  nlohmann::json j = to_json(s.registration);
  j["calibrating"] = s.calibrating;
  j["self_calibrate"] = "/api/camera/self-calibrate";
  j["last_self_calibration"] = s.last_self_calibration;
  return j;
}

Result<void> Daemon::Impl::setup_registration() {
  calibration_store.emplace(config.storage.data_dir / "calibration");
  calibration_key = fb::calibration_key(preview_camera->info());
  std::string source = is_default_calibration(preview_camera->info().calibration)
                           ? to_string(CalibrationSource::kDefaults)
                           : to_string(CalibrationSource::kDevice);
  std::string note;
  auto stored = calibration_store->load(calibration_key);
  if (!stored) {
    // A damaged file must not keep the booth from starting: the check will say whether the
    // camera's own calibration is good enough.
    note = "the stored calibration " + calibration_store->path_for(calibration_key).string() +
           " is unreadable (" + stored.error().message + "); using the camera's own";
    std::fprintf(stderr, "faceboothd: %s\n", note.c_str());
  } else if (*stored) {
    active_calibration = **stored;
    auto wrapped = with_active_calibration(std::move(preview_camera));
    if (!wrapped) return fail("the stored calibration: " + wrapped.error().message);
    preview_camera = std::move(*wrapped);
    source = "stored";
    note = calibration_store->path_for(calibration_key).string();
    std::fprintf(stderr, "faceboothd: camera calibration from %s\n", note.c_str());
  }
  RegistrationHealthOptions options;
  options.enabled = config.camera.registration_check;
  options.max_misregistration_px = config.camera.max_misregistration_px;
  RegistrationAdvice advice;
  advice.camera_uri = config.camera.uri;
  advice.store_path = calibration_store->path_for(calibration_key).string();
  health = std::make_unique<RegistrationHealth>(
      preview_camera->info().calibration, source, note, advice, options,
      [this](const RegistrationStatus& r) {
        refresh_led();  // first: a client that sees the new verdict sees its LED too
        update_status([&](StatusData& s) { s.registration = r; });
      });
  status.registration = health->status();
  return success();
}

Result<std::unique_ptr<DepthCamera>> Daemon::Impl::with_active_calibration(
    std::unique_ptr<DepthCamera> camera) {
  if (!active_calibration) return camera;
  auto wrapped = CalibratedCamera::wrap(std::move(camera), *active_calibration,
                                        "faceboothd: " + calibration_key);
  if (!wrapped) return wrapped.failure();
  return std::unique_ptr<DepthCamera>(std::move(*wrapped));
}

Result<void> Daemon::Impl::apply_calibration(const KinectCalibration& calibration,
                                             const std::string& source, const std::string& note) {
  active_calibration = calibration;
  if (auto* calibrated = dynamic_cast<CalibratedCamera*>(preview_camera.get())) {
    calibrated->set_calibration(calibration);
  } else {
    auto wrapped = with_active_calibration(std::move(preview_camera));
    if (!wrapped) {
      // The camera went with the failed wrap: open it again as it was.
      active_calibration.reset();
      auto reopened = open_camera(config.camera.uri);
      if (reopened && (*reopened)->start()) preview_camera = std::move(*reopened);
      return fail("cannot apply the calibration: " + wrapped.error().message);
    }
    preview_camera = std::move(*wrapped);
  }
  frames_since_loop = 0;
  if (health) health->recalibrated(preview_camera->info().calibration, source, note);
  return success();
}

Result<nlohmann::json> Daemon::Impl::self_calibrate(int frames) {
  const KioskState state = machine.state;  // on the worker (a worker job)
  // Between takes (and outside sessions) the camera is free; during a take, its processing or
  // tracking mode it is not.
  if (state == KioskState::kRecording || state == KioskState::kProcessing ||
      state == KioskState::kEnrolled || state == KioskState::kTracking)
    return fail(std::string("cannot calibrate while the kiosk is ") + to_string(state) +
                ": wait until the take is processed (or leave tracking mode), then try again");
  update_status([&](StatusData& s) {
    s.calibrating = true;
    s.message = "Calibrating the camera: stay in front of it and turn your head slowly...";
  });
  struct Done {  // the status leaves "calibrating" however the run ends
    Impl& d;
    ~Done() {
      d.update_status([](StatusData& s) { s.calibrating = false; });
    }
  } done{*this};

  const KinectCalibration current = preview_camera->info().calibration;
  SelfCalibrationOptions options;
  options.max_frames = std::min(frames, kCalibrationKeptFrames);
  SelfCalibrator calibrator(current, options);
  RgbdFrame frame;
  int got = 0, misses = 0, counted = 0;
  const auto t0 = Clock::now();
  while (got < frames) {
    watchdog_ping();
    if (stopping) return fail("the daemon is stopping; calibration abandoned");
    auto r = preview_camera->next_frame(frame, std::chrono::milliseconds(500));
    if (!r) return fail("camera: " + r.error().message + "; check the camera, then try again");
    if (*r != FrameStatus::kFrame) {
      if (*r == FrameStatus::kEndOfStream) loop_preview_camera();
      if (++misses > 20)
        return fail("the camera delivered no frames for calibration (" + std::to_string(got) +
                    " of " + std::to_string(frames) + "); check it is connected, then try again");
      continue;
    }
    ++frames_since_loop;
    calibrator.add_frame(frame.depth_mm, frame.color);
    ++got;
    if (got % 5 == 0 || got == frames) {
      preview.show(frame);
      update_status([&](StatusData& s) {
        s.frames_total += got - counted;
        s.message = "Calibrating the camera: " + std::to_string(got) + " of " +
                    std::to_string(frames) + " frames. Stay in front of it, turn your head slowly.";
      });
      counted = got;
    }
  }
  const double read_ms = ms_since(t0);
  const auto t1 = Clock::now();
  auto estimate = calibrator.estimate();
  const double estimate_ms = ms_since(t1);
  watchdog_ping();
  if (!estimate) return fail("self-calibration: " + estimate.error().message);
  const SelfCalibrationResult& e = *estimate;
  nlohmann::json report = {{"ok", e.ok},
                           {"applied", false},
                           {"misregistration_px", finite_or_zero(e.misregistration_px)},
                           {"residual_px", finite_or_zero(e.residual_px)},
                           {"residual_px_p95", finite_or_zero(e.residual_px_p95)},
                           {"confidence", finite_or_zero(e.confidence)},
                           {"frames", got},
                           {"frames_used", e.frames},
                           {"samples", e.samples},
                           {"correction", correction_json(e.correction)},
                           {"read_ms", read_ms},
                           {"estimate_ms", estimate_ms}};
  if (!e.ok) {
    report["why"] = e.why;
    report["message"] =
        "Self-calibration was not confident enough to use (" + e.why +
        "); nothing was changed. Put a person (or objects with clear outlines) 0.5-2 m in front "
        "of the camera, turn the head slowly, and try again; or calibrate with a checkerboard "
        "(facebooth camera calibrate --camera " +
        config.camera.uri + " --board 9x6:25mm --out " +
        calibration_store->path_for(calibration_key).string() + ").";
  } else {
    const KinectCalibration calibrated = with_registration(current, e.correction);
    const std::string note = "registration moved by " + fixed_or_zero(e.misregistration_px) +
                             " px, residual " + fixed_or_zero(e.residual_px, 2) + " px";
    if (auto ok =
            apply_calibration(calibrated, to_string(CalibrationSource::kSelfCalibration), note);
        !ok)
      return ok.failure();
    report["applied"] = true;
    const auto path = calibration_store->path_for(calibration_key);
    if (auto saved = calibration_store->save(calibration_key, calibrated); saved) {
      report["saved"] = path.string();
      report["message"] =
          "Camera calibrated: " + note + "; kept in " + path.string() + " for the next start.";
    } else {
      report["message"] = "Camera calibrated for now (" + note + "), but it could not be kept (" +
                          saved.error().message + "): check that " + path.parent_path().string() +
                          " is writable.";
    }
  }
  std::fprintf(stderr, "faceboothd: self-calibration: %s\n",
               report["message"].get<std::string>().c_str());
  update_status([&](StatusData& s) {
    s.last_self_calibration = report;
    s.message = report["message"].get<std::string>();
  });
  return report;
}

Result<nlohmann::json> Daemon::Impl::request_self_calibration(int frames) {
  auto promise = std::make_shared<std::promise<Result<nlohmann::json>>>();
  auto future = promise->get_future();
  {
    std::lock_guard lock(queue_mutex);
    if (stopping) return fail("the daemon is stopping");
    worker_jobs.push_back([this, promise, frames](bool run) {
      promise->set_value(run ? self_calibrate(frames) : fail("the daemon is stopping"));
    });
  }
  queue_cv.notify_all();
  // A run reads its frames at the camera's rate (1.5 s for 45) and estimates in about a
  // second; the bound only guards against a wedged worker.
  if (future.wait_for(std::chrono::seconds(120)) != std::future_status::ready)
    return fail("self-calibration did not finish within 120 s; check the camera");
  return future.get();
}

void Daemon::Impl::drain_worker_jobs() {
  std::deque<std::function<void(bool)>> jobs;
  {
    std::lock_guard lock(queue_mutex);
    jobs.swap(worker_jobs);
  }
  for (auto& job : jobs) job(false);
}

void Daemon::Impl::maybe_auto_calibrate(KioskState state) {
  if (!config.camera.self_calibrate || !health || !health->needs_calibration()) return;
  if (state != KioskState::kIdle && state != KioskState::kComplete) return;
  // A scene without a person fails to calibrate; trying again at once would only repeat that.
  if (Clock::now() - last_auto_calibration < std::chrono::minutes(1)) return;
  last_auto_calibration = Clock::now();
  std::fprintf(stderr, "faceboothd: the camera needs calibration; self-calibrating\n");
  if (auto r = self_calibrate(config.camera.self_calibrate_frames); !r)
    std::fprintf(stderr, "faceboothd: self-calibration failed: %s\n", r.error().message.c_str());
}

bool Daemon::Impl::refuse_session_start(const QueuedInput& in, KioskState state) {
  const bool starts = ((in.input == KioskInput::kStart || in.input == KioskInput::kPress) &&
                       (state == KioskState::kIdle || state == KioskState::kComplete)) ||
                      (in.input == KioskInput::kResume && state == KioskState::kIdle);
  if (!starts || !health || !health->needs_calibration()) return false;
  const RegistrationStatus r = health->status();
  std::fprintf(stderr, "faceboothd: session not started: the camera needs calibration (%.1f px)\n",
               r.decisive.misregistration_px);
  update_status([&](StatusData& s) {
    s.last_input = std::string(to_string(in.input)) + " (refused: camera needs calibration)";
    s.message = "Session not started. " + r.message;
  });
  return true;
}

bool Daemon::Impl::registration_allows_fit(CaptureCommit& commit, std::int64_t session, int index,
                                           QaReport& qa) {
  if (!health || !config.camera.registration_check) return true;
  if (commit.frames) {
    update_status([](StatusData& s) { s.fit_stage = "registration check"; });
    const std::string from =
        "capture " + std::to_string(index + 1) + " of session " + std::to_string(session);
    if (auto c = health->check_take(*commit.frames, from); !c)
      std::fprintf(stderr, "faceboothd: %s: registration not checked: %s\n", from.c_str(),
                   c.error().message.c_str());
    else if (c->valid)
      commit.qa_scores["misregistration_px"] = finite_or_zero(c->misregistration_px);
  }
  if (!health->needs_calibration()) return true;
  const RegistrationStatus r = health->status();
  qa.passed = false;
  qa.landmarks = qa.fit = "refused: camera needs calibration";
  qa.reason = "the camera needs calibration (depth and colour " +
              fixed_or_zero(r.decisive.misregistration_px) + " px apart, limit " +
              fixed_or_zero(r.limit_px) +
              " px), so this take was not fitted; calibrate it (\"Calibrate camera\" on the page, "
              "or POST /api/camera/self-calibrate), then record the take again";
  return false;
}

LedPattern Daemon::Impl::led_pattern(KioskState state) const {
  const LedPattern p = led_for(state);
  // The calibration pattern replaces "ready" only: recording, processing and errors say more.
  if (p == LedPattern::kReady && health && health->needs_calibration())
    return LedPattern::kCalibrate;
  return p;
}

void Daemon::Impl::refresh_led() {
  std::lock_guard lock(led_mutex);
  if (!started || stopping) return;
  KioskState state;
  {
    std::lock_guard status_lock(status_mutex);
    state = status.state;
  }
  gpio->set_pattern(led_pattern(state));
}

}  // namespace fb
