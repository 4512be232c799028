// The worker's side of the capture take (capture_take.hpp), the daemon's processing after a take
// (landmarks, quick fit, QA, commit) on the fit worker (fit_worker.hpp), the operator's landmark
// corrections, and the worker's side of tracking mode (tracking_mode.hpp: the frame loop feeds it
// and keeps the status).
//
// Threads: the worker (frame loop + state machine) hands a recorded take to the fit thread and
// keeps running; the fit thread posts the outcome (qa_passed / last_done / qa_failed, tagged with
// the session) back into the worker's queue. A stop discards queued jobs and abandons a job
// whose fit is running before it commits (the capture stays not done and is recorded again
// after a restart, exactly like a take interrupted by SIGTERM).
#include <malloc.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "algo/core/clock.hpp"
#include "algo/core/figure_text.hpp"
#include "firmware/daemon/daemon_impl.hpp"
#include "storage/asset_files.hpp"

namespace fb {
namespace {

std::string fixed(double v, int digits = 2) {
  return figure_text(v, digits);
}  // n/a, not nan

}  // namespace

void Daemon::Impl::post_input(KioskInput input, std::int64_t session) {
  {
    std::lock_guard lock(queue_mutex);
    queue.push_back({input, {}, session});
  }
  queue_cv.notify_all();
}

// ---------------------------------------------------------------------------------------------
// The capture take (the room: capture_take.hpp); the worker keeps the capture's records, opens
// the take's camera and shows the take in the status and the preview.

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

Result<bool> Daemon::Impl::record_take() {
  const std::int64_t session = machine.session;
  const int index = machine.capture_index;
  if (index < 0 || index >= static_cast<int>(guide.size()))
    return fail("no capture selected for recording");
  const int n = config.camera.capture_frames;
  TakeSettings settings{n,
                        config.camera.stored_frame_stride,
                        config.storage.data_dir / "spool",
                        "no landmark detector (" + fitter_error + ")",
                        config.session.min_coverage,
                        config.session.min_fused_fraction,
                        config.session.max_residual_mm};
  {
    std::lock_guard lock(records_mutex);
    if (auto ok = records->begin_capture(session, index); !ok) return ok.failure();
  }
  if (auto ok = capture.start(settings); !ok) return ok.failure();
  update_status([&](StatusData& s) {
    ++s.attempts;
    s.take_frames = 0;
    s.message = "Recording: turn your head slowly left and right...";
  });
  auto take_camera = open_take_camera(index, n);
  if (!take_camera) return take_camera.failure();
  DepthCamera& camera = *take_camera ? **take_camera : *preview_camera;
  TakeHooks hooks;
  hooks.cancelled = [this] {
    watchdog_ping();
    return stopping || cancel_pending();
  };
  hooks.show = [this](const RgbdFrame& frame, const FaceBox& box) { preview.show(frame, box); };
  hooks.recorded = [this](int recorded) {
    update_status([&](StatusData& s) {
      s.take_frames = recorded;
      ++s.frames_total;
    });
  };
  hooks.ended = [this](long long missed) {
    update_status([&](StatusData& s) { s.frames_dropped += missed; });
  };
  return capture.record(camera, hooks);
}

// ---------------------------------------------------------------------------------------------
// Landmarks and the quick fit

Result<void> Daemon::Impl::start_fitter() {
  if (!config.session.quick_fit) {
    fitter_error = "off ([session] quick_fit = false)";
    return success();
  }
  QuickFitPaths paths;
  paths.face_model =
      config.session.face_model.empty() ? default_face_model_path() : config.session.face_model;
  paths.shape_predictor = config.session.shape_predictor;
  auto f = QuickFitter::create(paths, guide);
  if (!f) return f.failure();
  fitter = std::move(*f);
  std::fprintf(stderr, "faceboothd: landmark model loaded in %.0f ms (%s)\n",
               fitter->landmark_model_load_ms(), paths.shape_predictor.c_str());
  // The take's face detector is built now, not at the first take, where building dlib's HOG
  // detector (0.5-1 s) made the sensor overwrite the take's first 20 frames.
  capture.set_detector(fitter->share_landmark_detector(), face_proportions(fitter->model()));
  // Tracking after a restart uses the newest session's stored neutral.
  fit_worker.post([this](bool run) {
    if (!run) return;
    std::int64_t newest = 0;
    {
      std::lock_guard lock(records_mutex);
      if (auto all = records->sessions(); all && !all->empty()) newest = all->back().id;
    }
    if (newest > 0) ensure_session_neutral(newest);
  });
  return success();
}

void Daemon::Impl::ensure_session_neutral(std::int64_t session) {
  if (!fitter || fitter->neutral_session() == session) return;
  Result<std::optional<MeshData>> mesh = std::optional<MeshData>{};
  {
    std::lock_guard lock(records_mutex);
    mesh = records->neutral_mesh(session);
  }
  if (!mesh || !*mesh) return;
  if (auto ok = fitter->set_neutral(session, (*mesh)->positions); !ok) {
    std::fprintf(stderr, "faceboothd: stored neutral of session %lld unusable: %s\n",
                 static_cast<long long>(session), ok.error().message.c_str());
    return;
  }
  std::lock_guard lock(identity_mutex);
  subject_identity = fitter->identity();
  identity_session = session;
}

void Daemon::Impl::fold_fit_into_qa(const Result<QuickFitResult>& fit, QaReport& qa) {
  const auto& th = config.session;
  if (!fit) {
    const std::string& why = fit.error().message;
    const bool no_face = why.find("no face") != std::string::npos;
    qa.landmarks = no_face ? "failed" : "ok";
    qa.fit = "failed";
    if (qa.passed) {
      qa.passed = false;
      qa.reason = no_face ? "no face found by the landmark detector" : "quick fit failed: " + why;
    }
    return;
  }
  qa.landmarks = "ok";
  qa.fit = fit->neutral
               ? "neutral"
               : (fit->neutral_was_mean_face ? "expression (mean-face start)" : "expression");
  qa.landmark_score = fit->detection_score;
  qa.landmarks_3d = fit->landmarks_3d;
  qa.landmark_error_mm = fit->landmark_error_mm;
  qa.fit_rms_mm = fit->fit.rms_to_depth_mm;
  qa.fit_rms_initial_mm = fit->fit.rms_to_depth_mm_initial;
  qa.corrections = 0;
  for (bool c : fit->corrected) qa.corrections += c;
  if (!qa.passed) return;  // the take's own reason stays first
  if (qa.corrections == 0 && fit->detection_score < th.min_landmark_score)
    qa.reason = "landmark confidence " + fixed(fit->detection_score) + " below " +
                fixed(th.min_landmark_score);
  else if (!(fit->fit.rms_to_depth_mm <= th.max_fit_rms_mm))
    qa.reason = "fit residual " + fixed(fit->fit.rms_to_depth_mm) + " mm above " +
                fixed(th.max_fit_rms_mm) + " mm";
  else if (!(fit->landmark_error_mm <= th.max_landmark_error_mm))
    qa.reason = "landmarks disagree with the fit by " + fixed(fit->landmark_error_mm, 1) +
                " mm (correct them on the screen, or retry)";
  qa.passed = qa.reason.empty();
}

namespace {

void add_fit_scores(const QaReport& qa, std::map<std::string, double>& scores) {
  scores["landmark_score"] = qa.landmark_score;
  scores["landmarks_3d"] = qa.landmarks_3d;
  scores["landmark_error_mm"] = qa.landmark_error_mm;
  scores["fit_rms_mm"] = qa.fit_rms_mm;
  scores["fit_rms_initial_mm"] = qa.fit_rms_initial_mm;
  scores["fit_ms"] = qa.fit_ms;
  scores["landmark_corrections"] = qa.corrections;
}

}  // namespace

void Daemon::Impl::publish_qa_capture(const LastCapture& c) {
  QaCapture q;
  q.session = c.session;
  q.index = c.index;
  if (c.fit) {
    for (int i = 0; i < 68; ++i) {
      q.points.push_back({c.fit->color_points[static_cast<std::size_t>(i)].x(),
                          c.fit->color_points[static_cast<std::size_t>(i)].y()});
      q.corrected.push_back(c.fit->corrected[static_cast<std::size_t>(i)]);
    }
  }
  preview.set_capture_bmp(c.view.color.empty() ? std::string() : encode_bmp(c.view.color));
  update_status([&](StatusData& s) {
    q.revision = s.qa_capture.revision + 1;
    s.qa_capture = std::move(q);
    s.last_qa = c.qa;
  });
}

// The kProcess action's work, on the fit thread.
void Daemon::Impl::process_capture(std::int64_t session, int index, QaReport qa,
                                   CaptureCommit commit, CaptureView view, bool run) {
  if (!run) return;  // discarded at stop: begin_capture counted the attempt, nothing else
  LastCapture lc;
  lc.session = session;
  lc.index = index;
  // A misregistered camera lifts every landmark to the wrong depth: such a take is not fitted
  // (nor stored as done) but rejected with what to do.
  if (qa.passed && !registration_allows_fit(commit, session, index, qa))
    std::fprintf(stderr, "faceboothd: capture %d: %s\n", index, qa.reason.c_str());
  if (fitter && qa.passed) {
    update_status([](StatusData& s) { s.fit_stage = "landmarks and quick fit"; });
    if (index > 0) ensure_session_neutral(session);
    const auto t0 = Clock::now();
    auto fit = fitter->fit(session, index, view);
    qa.fit_ms = ms_since(t0);
    fold_fit_into_qa(fit, qa);
    std::fprintf(stderr,
                 "faceboothd: capture %d: %s, fit %s in %.0f ms (RMS %s mm, landmarks %s mm, "
                 "score %s)%s%s\n",
                 index, qa.landmarks.c_str(), qa.fit.c_str(), qa.fit_ms,
                 fixed(qa.fit_rms_mm).c_str(), fixed(qa.landmark_error_mm, 1).c_str(),
                 fixed(qa.landmark_score).c_str(), qa.passed ? "" : ": ", qa.reason.c_str());
    if (fit) {
      if (fit->neutral) {
        std::lock_guard lock(identity_mutex);
        subject_identity = fitter->identity();
        identity_session = session;
      }
      lc.fit = std::move(*fit);
    }
  } else if (!fitter) {
    qa.landmarks = qa.fit = fitter_error.empty() ? "off" : fitter_error;
  }
  if (stopping) return;  // abandoned before anything was written
  add_fit_scores(qa, commit.qa_scores);
  if (lc.fit) {
    // The fit's pose (camera_from_model), so the stored mesh can be put back onto the stored
    // depth without refitting.
    const RigidPose& p = lc.fit->fit.camera_from_model;
    const double pose[7] = {p.translation.x(), p.translation.y(), p.translation.z(), p.rotation.x(),
                            p.rotation.y(),    p.rotation.z(),    p.rotation.w()};
    const char* names[7] = {"fit_pose_tx", "fit_pose_ty", "fit_pose_tz", "fit_pose_qx",
                            "fit_pose_qy", "fit_pose_qz", "fit_pose_qw"};
    for (int i = 0; i < 7; ++i) commit.qa_scores[names[i]] = pose[i];
  }
  update_status([](StatusData& s) { s.fit_stage = "storing"; });

  KioskInput outcome = KioskInput::kQaFailed;
  std::string error;
  {
    std::lock_guard lock(records_mutex);
    if (!qa.passed) {
      if (auto ok = records->reject_capture(session, index, commit.qa_scores); !ok)
        error = ok.error().message;
      lc.commit = std::move(commit);  // a correction may still accept this take
    } else {
      if (lc.fit) commit.landmarks = lc.fit->stored_landmarks(view.intrinsics);
      if (auto ok = records->commit_capture(session, index, std::move(commit)); !ok) {
        error = ok.error().message;
      } else {
        lc.committed = true;
        if (lc.fit && records->keeps_fits()) {
          FitRecord rec{lc.fit->neutral, guide[static_cast<std::size_t>(index)].name,
                        fitter->mesh(*lc.fit)};
          if (auto ok = records->add_fit(session, index, rec); !ok) error = ok.error().message;
        }
        if (auto s = records->session(session); !s) {
          error = s.error().message;
        } else {
          outcome = s->complete ? KioskInput::kLastDone : KioskInput::kQaPassed;
          update_status([&](StatusData& st) {
            if (st.session == session) st.done_count = s->done_count;
          });
        }
      }
    }
  }
  lc.qa = qa;
  lc.view = std::move(view);
  publish_qa_capture(lc);
  last_capture = std::move(lc);
  update_status([&](StatusData& s) {
    s.fit_stage.clear();
    if (!error.empty()) s.error = error;
  });
  post_input(error.empty() ? outcome : KioskInput::kFailed, session);
}

Result<nlohmann::json> Daemon::Impl::correct_landmarks(
    std::int64_t session, int index, const std::vector<ColorCorrection>& corrections) {
  if (!fitter) return fail("landmarks are off: " + fitter_error);
  auto promise = std::make_shared<std::promise<Result<nlohmann::json>>>();
  auto future = promise->get_future();
  fit_worker.post([this, promise, session, index, corrections](bool run) {
    auto answer = [&]() -> Result<nlohmann::json> {
      if (!run) return fail("the daemon is stopping");
      if (!last_capture || last_capture->session != session || last_capture->index != index)
        return fail("only the latest processed capture can be corrected on the device" +
                    (last_capture ? " (session " + std::to_string(last_capture->session) +
                                        ", capture " + std::to_string(last_capture->index) + ")"
                                  : std::string(" (none yet)")));
      LastCapture& lc = *last_capture;
      if (!lc.fit)
        return fail("capture " + std::to_string(index) +
                    " has no landmarks to correct (the detector found no face or the take "
                    "failed before fitting); record it again");
      bool accept_now = false;
      if (!lc.committed) {
        // A rejected take can be accepted by a correction only while the kiosk still waits
        // for its retry (after a new take starts, the old one is gone).
        std::lock_guard lock(status_mutex);
        if (status.state != KioskState::kRetry || status.session != session ||
            status.capture_index != index)
          return fail("capture " + std::to_string(index) + " is being recorded again");
      }
      const auto t0 = Clock::now();
      if (auto ok = fitter->refit(session, index, lc.view, corrections, *lc.fit); !ok)
        return ok.failure();
      QaReport qa = lc.qa;
      qa.passed = qa.coverage >= config.session.min_coverage &&
                  qa.fused_fraction >= config.session.min_fused_fraction &&
                  qa.residual_mm <= config.session.max_residual_mm;
      qa.reason = qa.passed ? "" : lc.qa.reason;
      fold_fit_into_qa(*lc.fit, qa);
      qa.fit_ms = ms_since(t0);
      if (lc.fit->neutral) {
        std::lock_guard lock(identity_mutex);
        subject_identity = fitter->identity();
        identity_session = session;
      }
      const std::vector<Landmark> points = lc.fit->stored_landmarks(lc.view.intrinsics);
      std::optional<KioskInput> outcome;
      {
        std::lock_guard lock(records_mutex);
        if (!lc.committed && qa.passed) {
          CaptureCommit commit = std::move(lc.commit);
          lc.commit = {};
          add_fit_scores(qa, commit.qa_scores);
          commit.landmarks = points;
          if (auto ok = records->commit_capture(session, index, std::move(commit)); !ok)
            return ok.failure();
          lc.committed = true;
          accept_now = true;
          auto s = records->session(session);
          if (!s) return s.failure();
          outcome = s->complete ? KioskInput::kLastDone : KioskInput::kQaPassed;
          update_status([&](StatusData& st) { st.done_count = s->done_count; });
        } else if (!lc.committed) {
          add_fit_scores(qa, lc.commit.qa_scores);
          if (auto ok = records->reject_capture(session, index, lc.commit.qa_scores); !ok)
            return ok.failure();
        }
        if (lc.committed) {
          if (auto ok = records->set_operator_landmarks(session, index, points); !ok)
            return ok.failure();
          if (records->keeps_fits()) {
            FitRecord rec{lc.fit->neutral, guide[static_cast<std::size_t>(index)].name,
                          fitter->mesh(*lc.fit)};
            if (auto ok = records->add_fit(session, index, rec); !ok) return ok.failure();
          }
        }
      }
      lc.qa = qa;
      publish_qa_capture(lc);
      if (outcome) post_input(*outcome, session);
      return nlohmann::json{{"session", session},
                            {"capture", index},
                            {"accepted", accept_now},
                            {"committed", lc.committed},
                            {"qa",
                             {{"passed", qa.passed},
                              {"reason", qa.reason},
                              {"fit_rms_mm", figure_json(qa.fit_rms_mm)},
                              {"landmark_error_mm", figure_json(qa.landmark_error_mm)},
                              {"landmarks_3d", qa.landmarks_3d},
                              {"corrections", qa.corrections},
                              {"fit_ms", figure_json(qa.fit_ms)}}}};
    };
    auto result = answer();
    if (result)
      std::fprintf(stderr, "faceboothd: capture %d: %zu landmark correction(s), refit RMS %s mm\n",
                   index, corrections.size(),
                   fixed((*result)["qa"]["fit_rms_mm"].is_number()
                             ? (*result)["qa"]["fit_rms_mm"].get<double>()
                             : NAN)
                       .c_str());
    else
      std::fprintf(stderr, "faceboothd: capture %d: correction refused: %s\n", index,
                   result.error().message.c_str());
    promise->set_value(std::move(result));
  });
  // The fit takes well under a second here; the bound only guards against a wedged thread.
  if (future.wait_for(std::chrono::seconds(60)) != std::future_status::ready)
    return fail("the refit did not finish within 60 s");
  return future.get();
}

// ---------------------------------------------------------------------------------------------
// Tracking mode (the room: tracking_mode.hpp); the worker gathers whose face it is and keeps
// the status.

Result<void> Daemon::Impl::start_tracking() {
  update_status([](StatusData& s) {
    s.tracking_frames = 0;
    s.tracking_state.clear();
    s.tracking_reason.clear();
    s.tracking_note.clear();
  });
  if (!fitter) return fail("tracking needs the face model: " + fitter_error);
  // A session before leaves its freed buffers (fusion volumes, the fit thread's arena) in the
  // heap; hand them back before the tracker allocates, or the peak adds both.
  ::malloc_trim(0);
  std::int64_t take_session = machine.session;
  TrackingIdentity identity;
  identity.guide = &guide;  // immutable after create()
  {
    std::lock_guard lock(records_mutex);
    if (take_session == 0) {
      if (auto all = records->sessions(); all && !all->empty()) take_session = all->back().id;
    }
    if (take_session != 0) {
      auto found = records->rig_for(take_session);
      if (found) {
        identity.rig = std::move(*found);
      } else {
        std::fprintf(stderr, "faceboothd: tracking without the stored rig: %s\n",
                     found.error().message.c_str());
      }
    }
  }
  {
    std::lock_guard lock(identity_mutex);
    identity.neutral = subject_identity;
    identity.neutral_session = identity_session;
  }
  const std::string target = !config.streaming.vmc_target.empty() ? config.streaming.vmc_target
                                                                  : config.streaming.osc_target;
  // The face model is immutable after create(): safe on this thread.
  auto note =
      tracking.start(fitter->model(), preview_camera->info(), fitter->share_landmark_detector(),
                     std::move(identity), target, config.streaming.max_take_frames, take_session);
  if (!note) return note.failure();
  update_status([&](StatusData& s) {
    s.tracking_identity = *note;
    s.vmc_datagrams = 0;
    s.tracking_latency_median_ms = s.tracking_latency_p95_ms = s.tracking_ms_median = 0;
    s.tracking_reacquire = "dlib face detection on the colour image, then depth";
    s.tracking_detections = 0;
    s.tracking_occluded = false;
    s.tracking_hidden_fraction = 0;
    s.tracking_occluded_frames = 0;
  });
  std::fprintf(stderr, "faceboothd: tracking (%s), VMC %s\n", note->c_str(),
               target.empty() ? "off" : target.c_str());
  return success();
}

void Daemon::Impl::stop_tracking() {
  if (!tracking.active()) return;
  std::string note;
  std::int64_t take_id = 0;
  TakeWriter* take = tracking.take();
  if (config.streaming.save_takes && take && take->frame_count() > 0) {
    TakeRecord whose;
    whose.session = tracking.take_session();
    whose.subject_name = "tracking";
    std::lock_guard lock(records_mutex);
    auto id = records->add_take(whose, *take);
    if (id) {
      take_id = *id;
      note = "take " + std::to_string(*id) + " stored (" + std::to_string(take->frame_count()) +
             " frames; the face was occluded on " + std::to_string(tracking.occluded_frames()) +
             ")";
    } else {
      note = "take not stored: " + id.error().message;
    }
  }
  tracking.stop();
  update_status([&](StatusData& s) {
    s.tracking_note = note;
    if (take_id > 0) s.last_take = take_id;
  });
  if (!note.empty()) std::fprintf(stderr, "faceboothd: %s\n", note.c_str());
}

void Daemon::Impl::tracking_tick() {
  const auto t0 = Clock::now();
  RgbdFrame frame;
  auto got = preview_camera->next_frame(frame, std::chrono::milliseconds(100));
  if (got && *got == FrameStatus::kEndOfStream) return loop_preview_camera();
  if (!got || *got != FrameStatus::kFrame) return;
  const auto arrival = Clock::now();
  ++frames_since_loop;
  health->offer(frame);
  preview.show(frame);
  bool state_changed = false;
  if (tracking.active()) {
    const TrackingMode::Tick tick = tracking.track(frame, arrival);
    if (tick.detected) update_status([](StatusData& s) { ++s.tracking_detections; });
    if (!tick.send_error.empty())
      update_status([&](StatusData& s) { s.tracking_note = tick.send_error; });
    std::lock_guard lock(status_mutex);
    // A hand arriving or leaving is pushed at once too, not at the next half-second.
    state_changed = status.tracking_state != tracking.state() || tick.occlusion_changed;
  }
  // The status (and its SSE stream) changes on tracker state changes and twice a second; the
  // per-frame weights go through the live stream.
  long long frames;
  {
    std::lock_guard lock(status_mutex);
    frames = ++status.frames_total;
    ++status.tracking_frames;
  }
  if (state_changed || frames % 15 == 0) {
    const TrackingMode::Figures f = tracking.figures();
    update_status([&](StatusData& s) {
      s.tracking_state = f.state;
      s.tracking_reason = f.reason;
      s.tracking_occluded = f.occluded;
      s.tracking_hidden_fraction = f.hidden_fraction;
      s.tracking_occluded_frames = f.occluded_frames;
      s.vmc_datagrams = f.vmc_datagrams;
      s.tracking_latency_median_ms = f.latency_median_ms;
      s.tracking_latency_p95_ms = f.latency_p95_ms;
      s.tracking_ms_median = f.track_ms_median;
    });
  }
  if (config.camera.realtime) {
    const auto period = std::chrono::duration<double>(1.0 / preview_camera->info().fps);
    std::this_thread::sleep_until(t0 + std::chrono::duration_cast<Clock::duration>(period));
  }
}

}  // namespace fb
