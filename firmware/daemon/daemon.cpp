#include "firmware/daemon/daemon.hpp"
#include "algo/core/clock.hpp"

#include <malloc.h>
#include <poll.h>
#include <pthread.h>
#include <systemd/sd-daemon.h>

#include <cmath>
#include <csignal>
#include <cstring>
#include <ctime>
#include <fstream>
#include <sstream>

#include "algo/core/figure_text.hpp"
#include "drivers/camera/common/device_json.hpp"
#include "firmware/daemon/daemon_impl.hpp"

namespace fb {

// ---------------------------------------------------------------------------------------------
// Creation and lifetime

Daemon::Daemon(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Daemon::~Daemon() {
  stop();
}

Result<std::unique_ptr<Daemon>> Daemon::create(const DaemonConfig& config,
                                               const DaemonOptions& options) {
  auto impl = std::make_unique<Impl>();
  impl->config = config;
  impl->options = options;
  if (auto ok = validate_daemon_config(config); !ok) return ok.failure();

  if (options.handle_signals) {
    // Block the stop signals first, so every thread started later (ours, and any a library
    // starts while loading models) inherits the mask; they are
    // then only ever read from the daemon's signalfd (no async handler, no global state).
    sigset_t mask;
    sigemptyset(&mask);
    sigaddset(&mask, SIGTERM);
    sigaddset(&mask, SIGINT);
    if (pthread_sigmask(SIG_BLOCK, &mask, nullptr) != 0) return fail("cannot block signals");
    impl->signal_fd.reset(::signalfd(-1, &mask, SFD_CLOEXEC | SFD_NONBLOCK));
    if (impl->signal_fd.get() < 0)
      return fail(std::string("signalfd failed: ") + std::strerror(errno));
  }
  impl->token = config.http.token;
  if (!config.http.token_file.empty()) {
    std::ifstream in(config.http.token_file);
    if (!in) return fail("cannot read http.token_file '" + config.http.token_file.string() + "'");
    std::getline(in, impl->token);
  }

  auto guide = load_guide_steps(config.session.guide_file);
  if (!guide) return guide.failure();
  impl->guide = std::move(*guide);

  std::error_code ec;
  std::filesystem::create_directories(config.storage.data_dir, ec);
  if (ec)
    return fail("cannot create the data directory '" + config.storage.data_dir.string() +
                "': " + ec.message());
  auto booth_id = load_booth_id(config.storage.data_dir);
  if (!booth_id) return booth_id.failure();
  impl->booth_id = std::move(*booth_id);
  FrameSpool::remove_stale(config.storage.data_dir / "spool");  // takes of a crashed run
  auto records = open_session_records(config.storage.data_dir);
  if (!records) return fail("cannot open the session store: " + records.error().message);
  impl->records = std::move(*records);

  // The HTTP port is bound before the seconds of model loading, so it is ours from the start (a
  // port in use fails here); requests are served once start() listens.
  if (config.http.enabled)
    if (auto ok = impl->setup_http(); !ok) return ok.failure();

  // The landmark model and the face model, loaded once (the largest part of the daemon's memory).
  if (auto ok = impl->start_fitter(); !ok)
    return fail("landmarks and quick fit: " + ok.error().message +
                " (or set [session] quick_fit = false)");

  auto gpio = open_gpio(config.gpio);
  if (!gpio) return gpio.failure();
  impl->gpio = std::move(*gpio);

  auto camera = open_camera(config.camera.uri);
  if (!camera)
    return fail("cannot open camera '" + config.camera.uri + "': " + camera.error().message);
  impl->preview_camera = std::move(*camera);
  // The unit's stored calibration (if any) and the registration check, before the first frame.
  if (auto ok = impl->setup_registration(); !ok) return ok.failure();
  if (auto ok = impl->preview_camera->start(); !ok)
    return fail("cannot start camera '" + config.camera.uri + "': " + ok.error().message);
  impl->capture.warm_up(impl->preview_camera->info());

  impl->wake_fd.reset(::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK));
  if (impl->wake_fd.get() < 0) return fail(std::string("eventfd failed: ") + std::strerror(errno));

  std::uint64_t usec = 0;
  if (sd_watchdog_enabled(0, &usec) > 0) impl->watchdog_usec = usec;

  // Resume after a power loss (or a stop) in the middle of a session.
  if (config.session.resume) {
    std::lock_guard lock(impl->records_mutex);
    if (auto all = impl->records->sessions(); all && !all->empty() && !all->back().complete) {
      impl->queue.push_back({KioskInput::kResume, {}, all->back().id});
      impl->status.resumed = true;
    }
  }
  impl->status.capture_count = static_cast<int>(impl->guide.size());
  impl->status.message = "Press the button to start";
  return std::unique_ptr<Daemon>(new Daemon(std::move(impl)));
}

Result<void> Daemon::start() {
  auto& d = *impl_;
  if (d.started.exchange(true)) return success();
  d.refresh_led();
  d.worker_thread = std::thread([&d] { d.worker_loop(); });
  d.fit_worker.start();
  d.gpio_thread = std::thread([&d] { d.gpio_loop(); });
  if (d.http) {
    d.http_thread = std::thread([&d] {
      run_in_background();  // and its pool's threads, started from this one
      d.http->listen_after_bind();
    });
    // The listener is bound already; wait until it accepts so READY=1 means reachable.
    for (int i = 0; i < 200 && !d.http->is_running(); ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  d.ready = true;
  d.update_status([&](StatusData& s) { s.start_to_ready_ms = ms_since(d.created_at); });
  sd_notifyf(0, "READY=1\nSTATUS=ready, http port %d\nMAINPID=%lu", d.http_port,
             static_cast<unsigned long>(::getpid()));
  return success();
}

Result<void> Daemon::run() {
  if (auto ok = start(); !ok) return ok;
  auto& d = *impl_;
  std::fprintf(stderr, "faceboothd: ready (camera %s, gpio %s, store %s at %s, http %s)\n",
               d.config.camera.uri.c_str(), d.gpio->info().backend.c_str(),
               d.records->backend().c_str(), d.records->root().c_str(),
               d.http ? (d.config.http.bind + ":" + std::to_string(d.http_port)).c_str() : "off");
  pollfd fds[2] = {{d.wake_fd.get(), POLLIN, 0}, {d.signal_fd.get(), POLLIN, 0}};
  const nfds_t n = d.signal_fd.get() >= 0 ? 2 : 1;
  while (!d.stopping) {
    const int r = ::poll(fds, n, 1000);
    if (r < 0 && errno != EINTR) break;
    if (n == 2 && (fds[1].revents & POLLIN)) {
      signalfd_siginfo info{};
      if (::read(d.signal_fd.get(), &info, sizeof info) == sizeof info)
        std::fprintf(stderr, "faceboothd: %s, stopping\n",
                     strsignal(static_cast<int>(info.ssi_signo)));
      break;
    }
    if (fds[0].revents & POLLIN) break;
  }
  stop();
  return success();
}

void Daemon::request_stop() {
  impl_->stopping = true;
  const std::uint64_t one = 1;
  [[maybe_unused]] auto n = ::write(impl_->wake_fd.get(), &one, sizeof one);
  impl_->queue_cv.notify_all();
  impl_->status_cv.notify_all();
  impl_->fit_worker.request_stop();
  impl_->tracking.live().wake_all();
}

void Daemon::stop() {
  auto& d = *impl_;
  d.stopping = true;
  if (d.started) sd_notify(0, "STOPPING=1");
  d.queue_cv.notify_all();
  d.status_cv.notify_all();
  d.fit_worker.request_stop();
  d.tracking.live().wake_all();
  const auto t0 = Clock::now();
  if (d.http) d.http->stop();
  if (d.worker_thread.joinable()) d.worker_thread.join();
  d.fit_worker.join();
  for (auto* t : {&d.gpio_thread, &d.http_thread})
    if (t->joinable()) t->join();
  d.drain_worker_jobs();  // a calibration request still waiting is answered
  if (d.preview_camera) d.preview_camera->stop();
  if (d.started.exchange(false))
    std::fprintf(stderr, "faceboothd: stopped in %.0f ms\n", ms_since(t0));
  if (d.gpio) d.gpio->set_pattern(LedPattern::kOff);
  d.ready = false;
}

bool Daemon::ready() const {
  return impl_->ready;
}
int Daemon::http_port() const {
  return impl_->http_port;
}

void Daemon::post(KioskInput input, const std::string& subject, std::int64_t session) {
  {
    std::lock_guard lock(impl_->queue_mutex);
    impl_->queue.push_back({input, subject, session});
  }
  impl_->queue_cv.notify_all();
}

Result<void> Daemon::press(const ButtonEvent& event) {
  return simulate_press(*impl_->gpio, event);
}

std::uint64_t Daemon::wait_status(std::uint64_t seen, std::chrono::milliseconds timeout) const {
  std::unique_lock lock(impl_->status_mutex);
  impl_->status_cv.wait_for(lock, timeout,
                            [&] { return impl_->status_version != seen || impl_->stopping; });
  return impl_->status_version;
}

nlohmann::json Daemon::status() const {
  return impl_->status_json();
}

nlohmann::json Daemon::Impl::status_json() const {
  const auto& d = *this;
  // A snapshot under the lock, the JSON built outside it: the HTTP threads run at a lower
  // priority, and one preempted while holding the lock would stall the take's frame loop.
  std::uint64_t version = 0;
  const StatusData s = [&] {
    std::lock_guard lock(d.status_mutex);
    version = d.status_version;
    return d.status;
  }();
  nlohmann::json j = {
      {"version", version},
      {"ready", d.ready.load()},
      {"state", to_string(s.state)},
      {"message", s.message},
      {"last_input", s.last_input},
      {"session", s.session == 0 ? nlohmann::json(nullptr) : nlohmann::json(s.session)},
      {"subject", s.subject},
      {"resumed", s.resumed},
      {"capture_index", s.capture_index},
      {"capture_count", s.capture_count},
      {"done_count", s.done_count},
      {"attempts", s.attempts},
      {"take_frames", s.take_frames},
      {"take_length", d.config.camera.capture_frames},
      {"frames_total", s.frames_total},
      {"frames_dropped", s.frames_dropped},
      {"clock_steps", s.clock_steps},
      {"last_clock_step_s", s.last_clock_step_s},
      {"tracking_frames", s.tracking_frames},
      {"led", to_string(d.gpio->pattern())},
      {"registration", registration_json(s)},
      {"gpio", d.gpio->info().backend},
      {"camera", d.config.camera.uri},
      {"store", d.records->backend()},
      {"uptime_s", ms_since(d.created_at) / 1000.0},
      {"start_to_ready_ms", s.start_to_ready_ms},
      // The device pipeline after fusion.
      {"stages",
       {{"fusion", "on"},
        {"landmarks", d.fitter ? "dlib 68-point" : d.fitter_error},
        {"quick_fit", d.fitter ? "on" : d.fitter_error},
        {"landmark_model_load_ms", d.fitter ? d.fitter->landmark_model_load_ms() : 0.0},
        {"fit_stage", s.fit_stage},
        {"store_keeps_fits", d.records->keeps_fits()}}},
      {"tracking",
       {{"pipeline", d.fitter ? "on" : "off: " + d.fitter_error},
        {"vmc_target", !d.config.streaming.vmc_target.empty() ? d.config.streaming.vmc_target
                                                              : d.config.streaming.osc_target},
        {"state", s.tracking_state},
        {"reason", s.tracking_reason},
        {"identity", s.tracking_identity},
        {"frames", s.tracking_frames},
        {"vmc_datagrams", s.vmc_datagrams},
        {"latency_ms",
         {{"median", s.tracking_latency_median_ms}, {"p95", s.tracking_latency_p95_ms}}},
        {"track_ms_median", s.tracking_ms_median},
        {"reacquire", s.tracking_reacquire},
        {"detections", s.tracking_detections},
        {"occluded", s.tracking_occluded},
        {"hidden_fraction", s.tracking_hidden_fraction},
        {"occluded_frames", s.tracking_occluded_frames},
        {"last_take", s.last_take},
        {"note", s.tracking_note},
        {"live", "/api/tracking/events"}}},
  };
  if (s.capture_index >= 0 && s.capture_index < static_cast<int>(d.guide.size())) {
    j["expression"] = {{"name", d.guide[s.capture_index].name},
                       {"label", d.guide[s.capture_index].label}};
  }
  if (s.last_qa) {
    j["qa"] = {{"coverage", figure_json(s.last_qa->coverage)},
               {"residual_mm", figure_json(s.last_qa->residual_mm)},
               {"fused_fraction", figure_json(s.last_qa->fused_fraction)},
               {"passed", s.last_qa->passed},
               {"reason", s.last_qa->reason},
               {"landmarks", s.last_qa->landmarks},
               {"fit", s.last_qa->fit},
               {"landmark_score", figure_json(s.last_qa->landmark_score)},
               {"landmarks_3d", s.last_qa->landmarks_3d},
               {"landmark_error_mm", figure_json(s.last_qa->landmark_error_mm)},
               {"fit_rms_mm", figure_json(s.last_qa->fit_rms_mm)},
               {"fit_rms_initial_mm", figure_json(s.last_qa->fit_rms_initial_mm)},
               {"fit_ms", figure_json(s.last_qa->fit_ms)},
               {"corrections", s.last_qa->corrections}};
    if (s.qa_capture.index >= 0) {
      j["qa"]["capture"] = {
          {"session", s.qa_capture.session},
          {"index", s.qa_capture.index},
          {"revision", s.qa_capture.revision},
          {"image", "/api/qa/capture.bmp?r=" + std::to_string(s.qa_capture.revision)},
          {"points", s.qa_capture.points},
          {"corrected", s.qa_capture.corrected}};
    }
  }
  if (!s.error.empty()) j["error"] = s.error;
  if (!s.last_export.empty()) j["last_export"] = s.last_export.string();
  return j;
}

// ---------------------------------------------------------------------------------------------
// Worker: the frame loop and the state machine

void Daemon::Impl::set_state(KioskState s, const std::string& input_name,
                             const std::string& message) {
  std::lock_guard lock(led_mutex);
  gpio->set_pattern(led_pattern(s));
  machine.state = s;
  update_status([&](StatusData& st) {
    st.state = s;
    st.last_input = input_name;
    if (!message.empty()) st.message = message;
  });
}

std::string Daemon::Impl::qa_failure_reason() {
  std::lock_guard lock(status_mutex);
  if (!status.last_qa) return "no quality report";
  return status.last_qa->reason.empty() ? "no reason given" : status.last_qa->reason;
}

void Daemon::Impl::watchdog_ping() {
  if (watchdog_usec == 0) return;
  const auto period = std::chrono::microseconds(watchdog_usec / config.watchdog_divisor);
  if (Clock::now() - last_watchdog >= period) {
    sd_notify(0, "WATCHDOG=1");
    last_watchdog = Clock::now();
  }
}

void Daemon::Impl::check_wall_clock() {
  const auto step = wall_clock.check();
  if (!step) return;
  std::fprintf(stderr,
               "faceboothd: the wall clock was set %s by %.0f s (NTP or an operator); takes and "
               "timeouts keep to the monotonic clock, stored times follow the new one\n",
               *step > 0 ? "forward" : "back", std::abs(*step));
  update_status([&](StatusData& s) {
    ++s.clock_steps;
    s.last_clock_step_s = *step;
  });
}

void Daemon::Impl::gpio_loop() {
  while (!stopping) {
    auto events = gpio->wait_events(std::chrono::milliseconds(100));
    if (!events) {
      update_status([&](StatusData& s) { s.error = events.error().message; });
      std::this_thread::sleep_for(std::chrono::milliseconds(500));
      continue;
    }
    for (const auto& e : *events) {
      KioskState state;
      {
        std::lock_guard lock(status_mutex);
        state = status.state;
      }
      {
        std::lock_guard lock(queue_mutex);
        queue.push_back({input_for(e, state), {}, 0});
      }
      queue_cv.notify_all();
    }
  }
}

void Daemon::Impl::worker_loop() {
  last_watchdog = Clock::now() - std::chrono::hours(1);
  auto last_preview = Clock::now() - std::chrono::hours(1);
  // Leaves only through the stopping branch below, so a stop that arrives while a tracking
  // frame is processed still stores the take (a `while (!stopping)` lost it).
  while (true) {
    watchdog_ping();
    check_wall_clock();
    std::optional<QueuedInput> input;
    std::function<void(bool)> job;
    const KioskState state = machine.state;
    const bool in_tracking = state == KioskState::kTracking;
    auto wait = std::chrono::milliseconds(100);
    if (in_tracking) wait = std::chrono::milliseconds(1);
    {
      std::unique_lock lock(queue_mutex);
      queue_cv.wait_for(lock, wait,
                        [&] { return !queue.empty() || !worker_jobs.empty() || stopping.load(); });
      if (!queue.empty()) {
        input = queue.front();
        queue.pop_front();
      } else if (!worker_jobs.empty()) {
        job = std::move(worker_jobs.front());
        worker_jobs.pop_front();
      }
    }
    if (stopping) {
      if (tracking.active()) stop_tracking();  // the take so far is stored, not lost
      if (job) job(false);
      break;
    }
    if (input) {
      handle(*input);
      continue;
    }
    if (job) {
      job(true);
      continue;
    }
    maybe_auto_calibrate(state);
    if (in_tracking) {
      tracking_tick();
    } else if (config.camera.preview_fps > 0 &&
               ms_since(last_preview) >= 1000.0 / config.camera.preview_fps) {
      last_preview = Clock::now();
      preview_tick();
    }
  }
}

void Daemon::Impl::preview_tick() {
  static_assert(true);
  RgbdFrame frame;
  auto got = preview_camera->next_frame(frame, std::chrono::milliseconds(50));
  if (!got) {
    update_status([&](StatusData& s) { s.error = "camera: " + got.error().message; });
    return;
  }
  if (*got == FrameStatus::kEndOfStream) return loop_preview_camera();
  if (*got != FrameStatus::kFrame) return;
  ++frames_since_loop;
  health->offer(frame);
  preview.show(frame, default_face_box(frame.color.width, frame.color.height));
  update_status([](StatusData& s) { ++s.frames_total; });
}

// Recordings and synthetic takes end; the preview (and tracking mode) loops them. A camera that
// starts over when started again (the synthetic one) is kept; one that cannot, or that ends
// again before giving a frame (a replay that does not rewind), is replaced by a new one. Keeping
// it is what matters for memory: a synthetic camera holds its own face model and render
// buffers, and opening the next one while the last still lived put both in the peak every 90
// frames (bench daemon, tracking mode after a session: VmHWM 255-257 MB, budget 256).
void Daemon::Impl::loop_preview_camera() {
  preview_camera->stop();
  const bool rewound = frames_since_loop > 0 && preview_camera->start();
  frames_since_loop = 0;
  if (rewound) return;
  auto reopened = open_camera(config.camera.uri);
  if (!reopened) return;
  auto calibrated = with_active_calibration(std::move(*reopened));  // a stored calibration stays
  if (calibrated && (*calibrated)->start()) preview_camera = std::move(*calibrated);
}

bool Daemon::Impl::cancel_pending() {
  std::lock_guard lock(queue_mutex);
  for (auto it = queue.begin(); it != queue.end(); ++it) {
    if (it->input == KioskInput::kCancel) {
      queue.erase(it);
      return true;
    }
  }
  return false;
}

void Daemon::Impl::handle(const QueuedInput& first) {
  QueuedInput in = first;
  if (in.session != 0 && (in.input == KioskInput::kQaPassed || in.input == KioskInput::kLastDone ||
                          in.input == KioskInput::kQaFailed || in.input == KioskInput::kFailed)) {
    // An outcome from the fit thread: it only counts for the session it was computed for (a
    // cancel or a new session in between makes it stale).
    if (machine.session != in.session) return;
  }
  while (!stopping) {
    const KioskState state = machine.state;
    if (refuse_session_start(in, state)) return;
    auto t = kiosk_transition(state, in.input);
    if (!t) {
      update_status([&](StatusData& s) {
        s.last_input = std::string(to_string(in.input)) + " (ignored in " + to_string(state) + ")";
      });
      return;
    }
    // One line per transition: the journal then tells the story of every session. A failed
    // quality check says why on the same line (the fit thread published its report first).
    const std::string why = in.input == KioskInput::kQaFailed ? qa_failure_reason() : "";
    std::fprintf(stderr, "faceboothd: %s --%s--> %s%s%s\n", to_string(state), to_string(in.input),
                 to_string(t->next), why.empty() ? "" : ": ", why.c_str());
    // A guide screen is published together with its capture (index, attempts): a client that
    // keys its presses on (state, capture) must never see "guide" with the previous capture.
    // Likewise the retry screen comes with its reason, never with the "checking" text;
    // "tracking" comes with this run's counters, never the last run's frame count, and "idle"
    // after tracking once the take is stored and the live frame gone.
    const bool prepare_first =
        t->action == KioskAction::kShowGuide || t->action == KioskAction::kResumeSession ||
        t->action == KioskAction::kStartTracking || t->action == KioskAction::kStopTracking;
    const std::string message =
        why.empty() ? "" : "Quality check failed (" + why + "). Press the button to record again.";
    if (!prepare_first) set_state(t->next, to_string(in.input), message);
    bool followup = false;
    const KioskInput next = do_action(t->action, in, &followup);
    if (prepare_first) set_state(t->next, to_string(in.input));
    if (!followup) return;
    in = {next, {}, 0};
  }
}

// Performs an action; when it has an outcome the machine must see, returns it with *followup.
KioskInput Daemon::Impl::do_action(KioskAction action, const QueuedInput& in, bool* followup) {
  auto failed = [&](const Error& e) {
    update_status([&](StatusData& s) {
      s.error = e.message;
      s.message = "Something went wrong: " + e.message + ". Press the button.";
    });
    std::fprintf(stderr, "faceboothd: %s\n", e.message.c_str());
    *followup = true;
    return KioskInput::kFailed;
  };
  switch (action) {
    case KioskAction::kNone:
      if (in.input != KioskInput::kQaFailed)  // the retry's message came with its state
        update_status([](StatusData& s) {
          s.error.clear();
          s.message = "Press the button to start";
        });
      return in.input;
    case KioskAction::kEnroll: {
      if (auto ok = enroll(in.subject); !ok) return failed(ok.error());
      *followup = true;
      return KioskInput::kEnrolled;
    }
    case KioskAction::kResumeSession: {
      std::int64_t id = in.session;
      {
        std::lock_guard lock(records_mutex);
        auto s = records->session(id);
        if (!s) return failed(s.error());
        if (s->complete) return failed(Error{"session " + std::to_string(id) + " is complete"});
        machine.session = id;
        update_status([&](StatusData& st) {
          st.session = id;
          st.subject = s->subject_name;
          st.done_count = s->done_count;
          st.capture_count = s->capture_count;
          st.resumed = true;
        });
      }
      if (auto ok = show_next_guide(); !ok) return failed(ok.error());
      return in.input;
    }
    case KioskAction::kShowGuide:
      if (auto ok = show_next_guide(); !ok) return failed(ok.error());
      return in.input;
    case KioskAction::kRecord: {
      auto took = record_take();
      if (!took) return failed(took.error());
      *followup = true;
      return *took ? KioskInput::kTakeDone : KioskInput::kCancel;  // false = cancelled/stopping
    }
    case KioskAction::kProcess: {
      // Landmarks, quick fit, QA and the commit run on the fit thread; the frame loop goes on
      // (preview, watchdog) and the outcome comes back as a queued input for this session.
      const std::int64_t session = machine.session;
      const int index = machine.capture_index;
      RecordedTake take = capture.take_result();
      auto commit = std::make_shared<CaptureCommit>(std::move(take.commit));
      auto view = std::make_shared<CaptureView>(std::move(take.view));
      update_status([](StatusData& s) { s.message = "Checking the capture (landmarks, fit)..."; });
      fit_worker.post([this, session, index, qa = std::move(take.qa), commit, view](bool run) {
        process_capture(session, index, qa, std::move(*commit), std::move(*view), run);
      });
      return in.input;
    }
    case KioskAction::kAbandon:
      update_status([&](StatusData& s) {
        s.take_frames = 0;
        if (in.input == KioskInput::kCancel)
          s.message = "Session paused. Press the button for a new subject; it can be resumed.";
      });
      return in.input;
    case KioskAction::kFinish: {
      const std::int64_t session = machine.session;
      std::lock_guard lock(records_mutex);
      auto out = records->export_session(session, config.storage.data_dir / "exports",
                                         [this] { return stopping.load(); });
      if (!out) return failed(out.error());
      machine.capture_index = -1;
      update_status([&](StatusData& s) {
        s.last_export = *out;
        s.capture_index = -1;
        s.message = "Done! Session " + std::to_string(session) + " is stored and ready.";
      });
      return in.input;
    }
    case KioskAction::kStartTracking: {
      auto ok = start_tracking();
      update_status([&](StatusData& s) {
        s.message = ok ? "Tracking mode: look at the camera. Press mode to go back."
                       : "Tracking mode without the tracker (" + ok.error().message +
                             "). Press mode to go back.";
        if (!ok) s.tracking_note = ok.error().message;
      });
      return in.input;
    }
    case KioskAction::kStopTracking:
      stop_tracking();
      update_status([](StatusData& s) { s.message = "Press the button to start"; });
      return in.input;
  }
  return in.input;
}

Result<void> Daemon::Impl::enroll(const std::string& subject_in) {
  std::string subject = subject_in;
  if (subject.empty()) {
    const std::time_t t = std::time(nullptr);
    std::tm tm{};
    gmtime_r(&t, &tm);
    char buf[40];
    std::strftime(buf, sizeof buf, "subject-%Y%m%d-%H%M%S", &tm);
    subject = buf;
  }
  std::vector<std::string> names;
  for (const auto& g : guide) names.push_back(g.name);
  std::lock_guard lock(records_mutex);
  auto sid = records->add_subject(subject);
  if (!sid) return sid.failure();
  auto session = records->create_session(*sid, names);
  if (!session) return session.failure();
  machine.session = *session;
  update_status([&](StatusData& s) {
    s.session = *session;
    s.subject = subject;
    s.done_count = 0;
    s.capture_count = static_cast<int>(names.size());
    s.resumed = false;
    s.last_qa.reset();
    s.last_export.clear();
    s.error.clear();
  });
  return success();
}

Result<void> Daemon::Impl::show_next_guide() {
  const std::int64_t session = machine.session;
  std::lock_guard lock(records_mutex);
  auto caps = records->captures(session);
  if (!caps) return caps.failure();
  for (const auto& c : *caps) {
    if (c.state == RecordState::kDone) continue;
    const std::string label =
        c.index < static_cast<int>(guide.size()) ? guide[c.index].label : c.expression;
    machine.capture_index = c.index;
    update_status([&](StatusData& s) {
      s.capture_index = c.index;
      s.attempts = c.attempts;
      s.take_frames = 0;
      s.message = "Expression " + std::to_string(c.index + 1) + " of " +
                  std::to_string(caps->size()) + ": " + label +
                  ". Make the face, then press the button and turn your head slowly.";
    });
    return success();
  }
  return fail("session " + std::to_string(session) + " has no capture left to record");
}

Result<HeadlessResult> Daemon::run_headless_session(const std::string& subject, int max_attempts) {
  if (auto ok = start(); !ok) return ok.failure();
  auto& d = *impl_;
  if (d.gpio->info().backend != "sim")
    return fail("a headless session needs the simulated GPIO ([gpio] backend = \"sim\")");
  HeadlessResult result;
  // Acts once per distinct (state, capture, attempts): a press is never sent twice for the same
  // screen, however often the status changes while the daemon works.
  std::string acted;
  bool started_session = false;
  std::uint64_t version = 0;
  std::int64_t session = 0;
  const auto deadline_per_step = std::chrono::seconds(120);
  auto last_progress = Clock::now();
  int last_done = -1;
  while (true) {
    if (d.signal_fd.get() >= 0) {
      signalfd_siginfo info{};
      if (::read(d.signal_fd.get(), &info, sizeof info) == sizeof info) request_stop();
    }
    if (d.stopping) return fail("stopped before the session was complete");
    const nlohmann::json s = status();
    const std::string state = s["state"];
    const std::string key = state + "/" + std::to_string(s["capture_index"].get<int>()) + "/" +
                            std::to_string(s["attempts"].get<int>());
    if (s["done_count"].get<int>() != last_done) {
      last_done = s["done_count"];
      last_progress = Clock::now();
      if (started_session)
        std::fprintf(stderr, "faceboothd: session %lld: %d/%d captures done\n",
                     static_cast<long long>(session), last_done, s["capture_count"].get<int>());
    }
    if (Clock::now() - last_progress > deadline_per_step)
      return fail("no progress for 120 s in state '" + state + "'");
    if (state == "error")
      return fail(s.value("error", std::string("the daemon reported an error")));
    if (state == "idle" && s["registration"]["needs_calibration"] == true)
      return fail(s["registration"]["message"].get<std::string>());
    if (!started_session) {
      if (state == "guide" && s["resumed"].get<bool>()) {
        started_session = true;  // a resumed session after a power loss: finish that one
        session = s["session"].get<std::int64_t>();
      } else if (state == "idle" || state == "complete") {
        started_session = true;
        post(KioskInput::kStart, subject);
        acted = key;
      }
    } else if (state == "guide" && key != acted) {
      if (session == 0) session = s["session"].get<std::int64_t>();
      if (auto ok = press({ButtonId::kMain, PressKind::kShort}); !ok) return ok.failure();
      acted = key;
    } else if (state == "retry" && key != acted) {
      if (s["attempts"].get<int>() >= max_attempts)
        return fail("capture " + std::to_string(s["capture_index"].get<int>()) + " failed QA " +
                    std::to_string(max_attempts) +
                    " times: " + s["qa"].value("reason", std::string("?")));
      ++result.retries;
      if (auto ok = press({ButtonId::kMain, PressKind::kShort}); !ok) return ok.failure();
      acted = key;
    } else if (state == "complete" && s.contains("last_export") && session != 0 &&
               s["session"].get<std::int64_t>() == session) {
      result.session_id = session;
      result.export_folder = s["last_export"].get<std::string>();
      result.captures_done = s["done_count"];
      result.frames_total = s["frames_total"];
      result.frames_dropped = s["frames_dropped"];
      break;
    }
    version = wait_status(version, std::chrono::milliseconds(500));
  }
  std::lock_guard lock(d.records_mutex);
  result.store = d.records->root();
  if (auto info = d.records->session(result.session_id)) result.session_folder = info->folder;
  return result;
}

}  // namespace fb
