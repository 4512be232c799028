// What the lab's daemon benches (bench daemon, bench soak) share: finding and running a real
// faceboothd as a child process, free loopback ports, the HTTP load process, a UDP counter for
// the VMC stream, the daemon's memory, descriptors and threads read from /proc, and driving a
// kiosk session through the HTTP API with simulated button presses.
#pragma once

#include <sys/types.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>

#include "algo/core/result.hpp"

namespace httplib {
class Client;
}

namespace fb::cli {

// A binary of the project: `given`, else `build_relative` to facebooth-lab in the build tree
// (build/sim/), else `name` next to it, else /usr/bin/`name`; empty when none exists.
std::filesystem::path find_binary(const std::string& given, const std::string& build_relative,
                                  const std::string& name);
// The faceboothd binary (find_binary).
std::filesystem::path find_daemon(const std::string& given);

// Binds `fd` to a free loopback port; returns the port, or -1.
int bind_loopback(int fd);
int free_port();

// A field of /proc/PID/status in MB (VmRSS:, VmHWM:), 0 when unreadable.
double rss_mb(pid_t pid, const char* field);
// Open file descriptors and threads of a process (-1 when unreadable).
int open_fds(pid_t pid);
int thread_count(pid_t pid);

// A child process that is killed and reaped when this goes out of scope.
class Child {
 public:
  explicit Child(pid_t pid = -1) : pid_(pid) {}
  ~Child() { kill(9); }
  Child(const Child&) = delete;
  Child& operator=(const Child&) = delete;
  pid_t pid() const { return pid_; }
  // Sends `sig` and waits for the exit; returns the exit status (-1 if none).
  int kill(int sig);

 private:
  pid_t pid_;
};

// Starts faceboothd with `config` (stderr to `log`) as a child process.
Result<pid_t> spawn_daemon(const std::filesystem::path& daemon, const std::filesystem::path& config,
                           const std::filesystem::path& log);

// The load generator: a second process with `threads` keep-alive clients requesting status,
// sessions and the preview picture until killed. Writes its request count to `count_file`.
[[noreturn]] void run_load(int port, int threads, const std::filesystem::path& count_file);

// A UDP socket on a free loopback port that counts the datagrams it receives.
class UdpCounter {
 public:
  UdpCounter();
  ~UdpCounter();
  UdpCounter(const UdpCounter&) = delete;
  UdpCounter& operator=(const UdpCounter&) = delete;
  int port() const { return port_; }
  long long received() const { return received_; }

 private:
  int fd_ = -1;
  int port_ = -1;
  std::atomic<bool> stop_{false};
  std::atomic<long long> received_{0};
  std::thread reader_;
};

// GET /api/status as JSON (null when the daemon does not answer).
nlohmann::json daemon_status(httplib::Client& http);
// Waits until the status says ready (up to `timeout_s`); returns the time since `since`, in ms.
Result<double> wait_until_ready(httplib::Client& http, std::chrono::steady_clock::time_point since,
                                double timeout_s = 60.0);
// What the synthetic camera's real-time takes logged (render_ahead.hpp): frames rendered after
// their sensor time (> 0 means a drop figure measured the renderer, not the daemon) and the
// most memory its render-ahead slots held (part of the daemon's RSS, not the daemon's own).
struct CameraLog {
  int takes = 0;
  long long late = 0;
  double buffer_mb_max = 0, render_ms_max = 0;
};
CameraLog read_camera_log(const std::filesystem::path& log);

// Starts a session for `subject` and presses the main button at every guide and retry screen
// until it is complete; returns the last status. Fails on the error state, on a capture that
// fails its check three times, or after `timeout_s`.
Result<nlohmann::json> drive_session(httplib::Client& http, const std::string& subject,
                                     double timeout_s = 600.0);

}  // namespace fb::cli
