// Private: the daemon's state shared by daemon.cpp (worker, signals) and http_api.cpp.
#pragma once

#include <sys/eventfd.h>
#include <sys/signalfd.h>
#include <unistd.h>

#include <atomic>
#include <condition_variable>
#include <deque>
#include <map>
#include <mutex>
#include <optional>
#include <thread>

#include "algo/fusion/face_fusion.hpp"
#include "drivers/camera/depth_camera.hpp"
#include "firmware/daemon/daemon.hpp"
#include "firmware/daemon/guide_steps.hpp"

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

struct QaReport {
  double coverage = 0;        // fused face-box pixels / face-box pixels
  double residual_mm = 0;     // mean ICP RMS over fused frames
  double fused_fraction = 0;  // fused frames / recorded frames
  bool passed = false;
  std::string reason;  // why it failed
};

// Everything the status JSON shows; guarded by Daemon::Impl::status_mutex.
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
  std::string error;
  std::string message;  // kiosk text
  bool resumed = false;
  long long frames_total = 0;    // frames the frame loop took from the camera (all modes)
  long long frames_dropped = 0;  // frames a real-time sensor would have overwritten
  long long tracking_frames = 0;
  std::filesystem::path last_export;
  double start_to_ready_ms = 0;
};

struct Daemon::Impl {
  DaemonConfig config;
  DaemonOptions options;
  std::chrono::steady_clock::time_point created_at = std::chrono::steady_clock::now();
  std::string token;
  std::vector<GuideStep> guide;

  std::unique_ptr<Gpio> gpio;
  std::unique_ptr<SessionRecords> records;
  std::mutex records_mutex;  // SessionRecords is single-threaded; worker and HTTP share it

  std::unique_ptr<DepthCamera> preview_camera;  // worker only
  FaceFusion fusion;                            // worker only
  QaReport pending_qa;                          // the last take, between record and process
  CaptureCommit pending_commit;

  // Inputs for the worker.
  std::mutex queue_mutex;
  std::condition_variable queue_cv;
  std::deque<QueuedInput> queue;

  // Status, with a version for SSE and waiters.
  mutable std::mutex status_mutex;
  mutable std::condition_variable status_cv;
  StatusData status;
  std::uint64_t status_version = 0;

  // Preview picture (downsampled colour with the face box), written by the worker.
  mutable std::mutex preview_mutex;
  ColorImage preview;
  std::map<int, std::string> guide_bmp_cache;  // guarded by preview_mutex

  std::atomic<bool> stopping{false};
  std::atomic<bool> ready{false};
  std::atomic<bool> started{false};
  OwnedFd signal_fd;
  OwnedFd wake_fd;  // eventfd: request_stop() wakes run()

  std::unique_ptr<httplib::Server> http;
  int http_port = 0;
  std::thread worker_thread, gpio_thread, http_thread;

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
  Result<bool> record_take(QaReport& qa, CaptureCommit& commit);
  void preview_tick();
  void tracking_tick();
  void watchdog_ping();
  bool cancel_pending();
  void set_state(KioskState s, const std::string& input_name);
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

  // --- HTTP (http_api.cpp)
  Result<void> setup_http();
};

}  // namespace fb
