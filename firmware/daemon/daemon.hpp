// faceboothd's core: owns the camera, the GPIO backend, the session records, the HTTP API and
// the signal handling, and runs the kiosk state machine (session_machine.hpp) on one worker
// thread — the frame loop, which also pings the systemd watchdog. Inputs arrive from the GPIO
// thread, the HTTP API and the headless driver through one queue, so the state machine is only
// ever touched by the worker.
//
//   auto daemon = Daemon::create(config);      // opens everything, binds the HTTP port
//   daemon->run();                             // READY=1, serve until SIGTERM/SIGINT or stop
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "algo/core/image.hpp"
#include "algo/core/result.hpp"
#include "drivers/gpio/gpio.hpp"
#include "firmware/daemon/daemon_config.hpp"
#include "firmware/daemon/session_machine.hpp"
#include "firmware/daemon/session_records.hpp"

namespace fb {

struct DaemonOptions {
  // Block SIGTERM/SIGINT in the calling thread (inherited by every thread the daemon starts)
  // and receive them through a signalfd owned by the daemon. Off for embedding in tests that
  // stop the daemon with request_stop().
  bool handle_signals = true;
};

// What a finished headless session reports.
struct HeadlessResult {
  std::int64_t session_id = 0;
  std::filesystem::path store;           // the session store's folder
  std::filesystem::path session_folder;  // this session's data folder
  std::filesystem::path export_folder;
  int captures_done = 0;
  int retries = 0;
  long long frames_total = 0;
  long long frames_dropped = 0;
};

class Daemon {
 public:
  static Result<std::unique_ptr<Daemon>> create(const DaemonConfig& config,
                                                const DaemonOptions& options = {});
  ~Daemon();
  Daemon(const Daemon&) = delete;
  Daemon& operator=(const Daemon&) = delete;

  // Starts the worker, GPIO and HTTP threads, tells systemd READY=1, and blocks until a
  // SIGTERM/SIGINT (when handled) or request_stop(). Then stops everything: a take in progress
  // is abandoned (its capture stays not done and is recorded again on resume); everything
  // committed is already durable. Returns within about a second of the request.
  Result<void> run();
  // Starts the threads without blocking (tests, headless); stop() or the destructor ends them.
  Result<void> start();
  void request_stop();
  void stop();
  bool ready() const;

  // Thread-safe inputs.
  void post(KioskInput input, const std::string& subject = {}, std::int64_t session = 0);
  Result<void> press(const ButtonEvent& event);  // through the GPIO backend (sim only)

  // A JSON snapshot of the daemon (state, session, capture, QA, frames, LED, ...).
  nlohmann::json status() const;
  // Blocks until the status version passes `seen` or the timeout; returns the current version.
  std::uint64_t wait_status(std::uint64_t seen, std::chrono::milliseconds timeout) const;
  int http_port() const;  // the bound port (config port 0 picks one)

  // Runs one complete session with simulated presses (sim GPIO): start, ready at each guide,
  // retry on QA failure (up to max_attempts per capture), then exports it.
  Result<HeadlessResult> run_headless_session(const std::string& subject, int max_attempts = 3);

  struct Impl;

 private:
  explicit Daemon(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// Encodes an RGB image as a 24-bit BMP (the kiosk's preview and guide pictures: every browser
// shows BMP and it needs no codec library on the device).
std::string encode_bmp(const ColorImage& image);
// A POSIX ustar archive of the regular files under `folder` (export downloads), read piece by
// piece so a download never holds the whole bundle in memory.
class TarStream {
 public:
  // `mtime`: the entries' modification time (seconds since the epoch; 0 = now). The bundle
  // gives the session's start, so the same session is the same bytes every time (resume).
  static Result<TarStream> open(const std::filesystem::path& folder, const std::string& prefix,
                                std::int64_t mtime = 0);
  std::uint64_t size() const { return total_; }
  Result<std::string> read(std::uint64_t offset, std::uint64_t length) const;

 private:
  struct Entry {
    std::filesystem::path path;
    std::uint64_t size = 0;
    std::uint64_t offset = 0;  // of the header in the archive
    std::string header;
  };
  std::vector<Entry> entries_;
  std::uint64_t total_ = 0;
};
// The whole archive at once (small folders, tests).
Result<std::string> tar_folder(const std::filesystem::path& folder, const std::string& prefix);

}  // namespace fb
