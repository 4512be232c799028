// Private: the daemon's state shared by daemon.cpp (worker, signals), the pipeline and the HTTP
// handlers (http_routes.hpp). Its rooms have their own headers (and locks where other threads
// reach them): the capture take (capture_take.hpp), the fit worker (fit_worker.hpp) and
// tracking mode (tracking_mode.hpp); the status is a snapshot the worker and the fit worker
// publish (update_status) and everyone else copies (status_json).
#pragma once

#include <sys/eventfd.h>
#include <sys/signalfd.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <condition_variable>
#include <deque>
#include <functional>
#include <future>
#include <map>
#include <mutex>
#include <optional>
#include <thread>

#include "drivers/camera/common/calibrated_camera.hpp"
#include "drivers/camera/depth_camera.hpp"
#include "firmware/daemon/capture_take.hpp"
#include "firmware/daemon/daemon.hpp"
#include "firmware/daemon/fit_worker.hpp"
#include "firmware/daemon/guide_steps.hpp"
#include "firmware/daemon/live_preview.hpp"
#include "firmware/daemon/quick_fit.hpp"
#include "firmware/daemon/registration_health.hpp"
#include "firmware/daemon/tracking_mode.hpp"
#include "firmware/daemon/wall_clock_watch.hpp"

// After every Eigen header: httplib pulls in <resolv.h>, whose `_res` macro breaks Eigen.
#include <httplib.h>

namespace fb {

// Owns a file descriptor.
class OwnedFd {
 public:
  OwnedFd() = default;
  explicit OwnedFd(int fd) : fd_(fd) {}
  ~OwnedFd() { reset(); }
  OwnedFd(OwnedFd&& o) noexcept : fd_(std::exchange(o.fd_, -1)) {}
  OwnedFd& operator=(OwnedFd&& o) noexcept {
    if (this != &o) reset(std::exchange(o.fd_, -1));
    return *this;
  }
  int get() const { return fd_; }
  void reset(int fd = -1) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = fd;
  }

 private:
  int fd_ = -1;
};

struct QueuedInput {
  KioskInput input;
  std::string subject;
  std::int64_t session = 0;
};

// The capture whose landmarks the QA screen shows (the last one processed), as the page needs it.
struct QaCapture {
  std::int64_t session = 0;
  int index = -1;
  int revision = 0;  // bumps with each refit (the page reloads the picture/points)
  std::vector<std::array<double, 2>> points;  // 68 colour px
  std::vector<bool> corrected;
};

// Everything the status JSON shows; guarded by Daemon::Impl::status_mutex. state, session and
// capture_index are a snapshot of the worker's machine (Daemon::Impl::Machine).
struct StatusData {
  KioskState state = KioskState::kIdle;
  std::string last_input;
  std::int64_t session = 0;
  std::string subject;
  int capture_index = -1;
  int capture_count = 0;
  int done_count = 0;
  int attempts = 0;
  int take_frames = 0;  // frames recorded in the current take
  std::optional<QaReport> last_qa;
  QaCapture qa_capture;
  std::string fit_stage;  // what the fit thread is doing ("" = idle)
  std::string error;
  std::string message;  // kiosk text
  bool resumed = false;
  long long frames_total = 0;    // frames the frame loop took from the camera (all modes)
  long long frames_dropped = 0;  // frames a real-time sensor would have overwritten
  int clock_steps = 0;           // times the wall clock was set while the daemon ran
  double last_clock_step_s = 0;  // the last such step (positive: set forward)
  long long tracking_frames = 0;
  std::string tracking_state;     // the tracker's state of the last frame
  std::string tracking_reason;    // why it has no face then (TrackReport::loss_reason), or ""
  std::string tracking_identity;  // where the tracked identity came from
  long long vmc_datagrams = 0;
  std::string tracking_reacquire;     // how a lost face is found again
  long long tracking_detections = 0;  // frames the face detector found the face on
  // Occlusion as data: something in front of the face (TrackReport::occluded), the share of it
  // hidden, and on how many frames of this tracking run the face was occluded.
  bool tracking_occluded = false;
  double tracking_hidden_fraction = 0;
  long long tracking_occluded_frames = 0;
  // Over the last kLatencyWindow tracked frames: from the frame leaving the camera driver to its
  // VMC datagrams sent (or the weights ready, with VMC off), and the tracker's own share.
  double tracking_latency_median_ms = 0, tracking_latency_p95_ms = 0;
  double tracking_ms_median = 0;
  std::int64_t last_take = 0;  // id of the last stored take
  std::string tracking_note;   // e.g. why a take was not stored
  std::filesystem::path last_export;
  double start_to_ready_ms = 0;
  // Registration health (registration_health.hpp) and self-calibration.
  RegistrationStatus registration;
  bool calibrating = false;              // a self-calibration run is reading frames
  nlohmann::json last_self_calibration;  // its report; null until one ran
};
// The status JSON's "registration" object (daemon_calibration.cpp).
nlohmann::json registration_json(const StatusData& s);

// Lowers the calling thread's scheduling priority (nice) by `nice_increment`. The take's frame
// loop is the one thread with a deadline (the sensor overwrites a frame it reads late); the fit,
// HTTP, registration-check and face-detection threads yield to it (daemon_util.cpp).
constexpr int kBackgroundNice = 5;
void run_in_background(int nice_increment = kBackgroundNice);

// The booth's id, kept in `data_dir/booth-id` (created once, random): hosts key the sessions
// they sync by it, so two booths' session ids never collide (daemon_util.cpp).
Result<std::string> load_booth_id(const std::filesystem::path& data_dir);

struct Daemon::Impl {
  DaemonConfig config;
  DaemonOptions options;
  std::chrono::steady_clock::time_point created_at = std::chrono::steady_clock::now();
  std::string token;
  std::string booth_id;  // this booth's id for the hosts that sync it (load_booth_id)
  std::vector<GuideStep> guide;

  std::unique_ptr<Gpio> gpio;
  std::unique_ptr<SessionRecords> records;
  std::mutex records_mutex;  // SessionRecords is single-threaded; worker and HTTP share it

  std::unique_ptr<DepthCamera> preview_camera;  // worker only
  long long frames_since_loop = 0;              // preview_camera's frames since it (re)started
  // --- the capture take (capture_take.hpp): worker only; its result waits there between
  // record and process.
  CaptureTake capture;

  // --- landmarks + quick fit (daemon_pipeline.cpp), run by the fit worker (fit_worker below)
  // so the fit never blocks the frame loop or the HTTP threads.
  std::unique_ptr<QuickFitter> fitter;  // fit thread only (model() is immutable: any thread)
  std::string fitter_error;             // why there is no fitter (config off, model missing)
  struct LastCapture {                  // fit thread only
    std::int64_t session = 0;
    int index = -1;
    bool committed = false;
    bool last = false;  // committing it completes the session
    CaptureView view;
    std::optional<QuickFitResult> fit;
    QaReport qa;
    CaptureCommit commit;  // kept while rejected: a correction may still accept it
  };
  std::optional<LastCapture> last_capture;
  // The subject identity tracking uses (from the fit thread), guarded by identity_mutex.
  std::mutex identity_mutex;
  std::vector<float> subject_identity;
  std::int64_t identity_session = 0;

  // --- tracking mode (tracking_mode.hpp): started, fed and stopped by the worker; the HTTP
  // threads read its live weights (tracking.live(), under its own lock).
  TrackingMode tracking;

  // The kiosk machine's state: the worker's alone, read and written without a lock. Each change
  // is published into `status` in the same update; other threads read that snapshot and reach
  // the machine only through the input queue.
  struct Machine {
    KioskState state = KioskState::kIdle;
    std::int64_t session = 0;
    int capture_index = -1;
  };
  Machine machine;  // worker only

  // Inputs for the worker.
  std::mutex queue_mutex;
  std::condition_variable queue_cv;
  std::deque<QueuedInput> queue;

  // Status, with a version for SSE and waiters.
  mutable std::mutex status_mutex;
  mutable std::condition_variable status_cv;
  StatusData status;
  std::uint64_t status_version = 0;

  // The live preview and the last capture's picture (live_preview.hpp: its own lock).
  LivePreview preview;
  // The guide pictures, rendered on first request (tens of ms: under a lock of their own, not
  // the preview's, which the take's frame loop takes).
  std::mutex guide_bmp_mutex;
  std::map<int, std::string> guide_bmp_cache;  // guarded by guide_bmp_mutex

  std::atomic<bool> stopping{false};
  std::atomic<bool> ready{false};
  std::atomic<bool> started{false};
  OwnedFd signal_fd;
  OwnedFd wake_fd;  // eventfd: request_stop() wakes run()

  std::unique_ptr<httplib::Server> http;
  int http_port = 0;
  std::thread worker_thread, gpio_thread, http_thread;

  WallClockWatch wall_clock;  // worker only
  void check_wall_clock();
  std::uint64_t watchdog_usec = 0;
  std::chrono::steady_clock::time_point last_watchdog;

  // --- worker (daemon.cpp)
  void worker_loop();
  void gpio_loop();
  void handle(const QueuedInput& in);
  void apply(KioskInput input, const std::string& subject = {}, std::int64_t session = 0);
  KioskInput do_action(KioskAction action, const QueuedInput& in, bool* has_followup);
  Result<void> enroll(const std::string& subject);
  Result<void> show_next_guide();
  void preview_tick();
  void tracking_tick();
  // At the end of a recording or synthetic take: starts it over (see daemon.cpp).
  void loop_preview_camera();
  // daemon_pipeline.cpp
  // The worker's side of a take: the capture's bookkeeping, its camera and the status; the
  // take itself records in `capture`. False when cancelled or stopping.
  Result<bool> record_take();
  Result<std::unique_ptr<DepthCamera>> open_take_camera(int index, int frames);
  Result<void> start_fitter();
  void process_capture(std::int64_t session, int index, QaReport qa, CaptureCommit commit,
                       CaptureView view, bool run);
  void publish_qa_capture(const LastCapture& c);
  void fold_fit_into_qa(const Result<QuickFitResult>& fit, QaReport& qa);
  Result<nlohmann::json> correct_landmarks(std::int64_t session, int index,
                                           const std::vector<ColorCorrection>& corrections);
  void ensure_session_neutral(std::int64_t session);
  Result<void> start_tracking();
  void stop_tracking();
  void post_input(KioskInput input, std::int64_t session = 0);
  void watchdog_ping();
  bool cancel_pending();
  // Publishes the state (and, when given, the kiosk message with it, in one status update).
  void set_state(KioskState s, const std::string& input_name, const std::string& message = "");
  std::string qa_failure_reason();  // the last quality report's reason (for a qa_failed input)
  template <class F>
  void update_status(F&& f) {
    {
      std::lock_guard lock(status_mutex);
      f(status);
      ++status_version;
    }
    status_cv.notify_all();
  }

  nlohmann::json status_json() const;
  // The guide expression i rendered on a neutral synthetic head (cached BMP).
  Result<std::string> guide_picture(int index);

  // --- HTTP (http_api.cpp: the server and its route table)
  Result<void> setup_http();

  // --- registration health and calibration (daemon_calibration.cpp)
  std::optional<CalibrationStore> calibration_store;
  std::string calibration_key;  // the preview camera's unit
  // Worker only: the calibration every camera the worker opens is put under (a stored or
  // self-calibrated one); nullopt = the camera's own.
  std::optional<KinectCalibration> active_calibration;
  std::deque<std::function<void(bool run)>> worker_jobs;  // guarded by queue_mutex
  std::mutex led_mutex;  // the LED pattern follows the state and the registration together
  std::chrono::steady_clock::time_point last_auto_calibration{};

  // create(): loads the unit's stored calibration (wrapping the preview camera) and starts the
  // registration check.
  Result<void> setup_registration();
  // `camera` under active_calibration (unchanged when there is none).
  Result<std::unique_ptr<DepthCamera>> with_active_calibration(std::unique_ptr<DepthCamera> camera);
  Result<void> apply_calibration(const KinectCalibration& calibration, const std::string& source,
                                 const std::string& note);
  // Worker: reads `frames` preview frames, estimates the registration, applies and stores it
  // when the estimate is ok. The report says what happened either way.
  Result<nlohmann::json> self_calibrate(int frames);
  // Any thread: runs self_calibrate() on the worker and waits for its report.
  Result<nlohmann::json> request_self_calibration(int frames);
  void maybe_auto_calibrate(KioskState state);
  void drain_worker_jobs();
  // Refuses a session start on a camera that needs calibration (says why in the status).
  bool refuse_session_start(const QueuedInput& in, KioskState state);
  // Fit thread: checks the take's own frames; false (qa says why) when the camera needs
  // calibration, so the take is neither fitted nor stored.
  bool registration_allows_fit(CaptureCommit& commit, std::int64_t session, int index,
                               QaReport& qa);
  LedPattern led_pattern(KioskState state) const;
  void refresh_led();

  // Near the end: its jobs use the members above, so it is joined before they are destroyed.
  FitWorker fit_worker;
  // Last: its checker thread calls back into the members above, so it is destroyed first.
  std::unique_ptr<RegistrationHealth> health;
};

}  // namespace fb
