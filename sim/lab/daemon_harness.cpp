#include "sim/lab/daemon_harness.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <vector>

#include "algo/core/clock.hpp"

// httplib last: its <resolv.h> defines `_res`, which breaks Eigen headers included after it.
#include <httplib.h>

namespace fb::cli {

namespace fs = std::filesystem;
using nlohmann::json;

fs::path find_binary(const std::string& given, const std::string& build_relative,
                     const std::string& name) {
  if (!given.empty()) return given;
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  for (const fs::path& p : {self.parent_path() / build_relative, self.parent_path() / name,
                            fs::path("/usr/bin") / name})
    if (fs::exists(p, ec)) return fs::weakly_canonical(p, ec);
  return {};
}

fs::path find_daemon(const std::string& given) {
  return find_binary(given, "../firmware/daemon/faceboothd", "faceboothd");
}

int bind_loopback(int fd) {
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t len = sizeof a;
  if (fd >= 0 && ::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0 &&
      ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len) == 0)
    return ntohs(a.sin_port);
  return -1;
}

int free_port() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  const int port = bind_loopback(fd);
  if (fd >= 0) ::close(fd);
  return port;
}

double rss_mb(pid_t pid, const char* field) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind(field, 0) == 0) return std::stod(line.substr(std::strlen(field))) / 1024.0;
  return 0;
}

int open_fds(pid_t pid) {
  std::error_code ec;
  int n = 0;
  for (fs::directory_iterator it("/proc/" + std::to_string(pid) + "/fd", ec), end; !ec && it != end;
       it.increment(ec))
    ++n;
  return ec ? -1 : n;
}

int thread_count(pid_t pid) {
  const double threads = rss_mb(pid, "Threads:") * 1024.0;  // the field is a plain count
  return threads > 0 ? static_cast<int>(threads + 0.5) : -1;
}

int Child::kill(int sig) {
  if (pid_ <= 0) return -1;
  ::kill(pid_, sig);
  int status = 0;
  ::waitpid(pid_, &status, 0);
  pid_ = -1;
  return status;
}

Result<pid_t> spawn_daemon(const fs::path& daemon, const fs::path& config, const fs::path& log) {
  const pid_t pid = ::fork();
  if (pid < 0) return fail("fork failed: " + std::string(std::strerror(errno)));
  if (pid == 0) {
    std::freopen(log.c_str(), "w", stderr);
    ::execl(daemon.c_str(), daemon.c_str(), "--config", config.c_str(), nullptr);
    std::_Exit(127);
  }
  return pid;
}

void run_load(int port, int threads, const fs::path& count_file) {
  std::atomic<long long> requests{0};
  std::vector<std::thread> workers;
  for (int t = 0; t < threads; ++t)
    workers.emplace_back([&, t] {
      httplib::Client c("127.0.0.1", port);
      c.set_keep_alive(true);
      const char* paths[] = {"/api/status", "/api/sessions", "/api/preview.bmp", "/"};
      for (long long i = t;; ++i) {
        if (c.Get(paths[i % 4])) ++requests;
        if (i % 200 == 0) std::ofstream(count_file) << requests.load();
      }
    });
  for (auto& w : workers) w.join();
  std::_Exit(0);
}

UdpCounter::UdpCounter() {
  fd_ = ::socket(AF_INET, SOCK_DGRAM, 0);
  port_ = bind_loopback(fd_);
  if (port_ > 0) {
    // A receive timeout, so the reader sees stop_ without relying on shutdown() waking it.
    timeval timeout{0, 200000};
    ::setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
    reader_ = std::thread([this] {
      char buffer[2048];
      while (!stop_)
        if (::recv(fd_, buffer, sizeof buffer, 0) > 0) ++received_;
    });
  }
}

UdpCounter::~UdpCounter() {
  stop_ = true;
  if (fd_ >= 0) ::shutdown(fd_, SHUT_RDWR);
  if (reader_.joinable()) reader_.join();
  if (fd_ >= 0) ::close(fd_);
}

json daemon_status(httplib::Client& http) {
  auto r = http.Get("/api/status");
  return r && r->status == 200 ? json::parse(r->body, nullptr, false) : json();
}

Result<double> wait_until_ready(httplib::Client& http, Clock::time_point since, double timeout_s) {
  const auto t0 = Clock::now();
  while (ms_since(t0) < timeout_s * 1000.0) {
    const json s = daemon_status(http);
    if (!s.is_null() && !s.is_discarded() && s.value("ready", false)) return ms_since(since);
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return fail("faceboothd never became ready within " +
              std::to_string(static_cast<int>(timeout_s)) + " s");
}

CameraLog read_camera_log(const fs::path& log) {
  std::ifstream in(log);
  CameraLog out;
  for (std::string line; std::getline(in, line);) {
    long long rendered = 0, held = 0, delivered = 0, overwritten = 0, late = 0;
    double ms = 0, mb = 0;
    if (std::sscanf(line.c_str(),
                    "synthetic camera: real-time take: %lld frames rendered (%lf ms each), %lld "
                    "slots held (%lf MB), %lld delivered, %lld overwritten, %lld late",
                    &rendered, &ms, &held, &mb, &delivered, &overwritten, &late) == 7) {
      ++out.takes;
      out.late += late;
      out.buffer_mb_max = std::max(out.buffer_mb_max, mb);
      out.render_ms_max = std::max(out.render_ms_max, ms);
    }
  }
  return out;
}

Result<json> drive_session(httplib::Client& http, const std::string& subject, double timeout_s) {
  const auto t0 = Clock::now();
  const json start = {{"subject", subject}};
  auto started = http.Post("/api/session/start", start.dump(), "application/json");
  if (!started || started->status != 202)
    return fail("faceboothd refused to start a session" +
                (started ? ": HTTP " + std::to_string(started->status) + " " + started->body
                         : std::string(": no answer")));
  std::string acted;
  bool began = false;
  while (true) {
    const json last = daemon_status(http);
    if (last.is_null() || last.is_discarded()) return fail("faceboothd stopped answering");
    const std::string state = last["state"];
    const std::string key = state + std::to_string(last["capture_index"].get<int>()) +
                            std::to_string(last["attempts"].get<int>());
    if (state == "error") return fail("faceboothd: " + last.value("error", "?"));
    // A status from before the start was taken (the previous session's "complete") is not
    // this session's end: that needs a guide screen first.
    if (state == "guide") began = true;
    if (state == "complete" && began) return last;
    if ((state == "guide" || state == "retry") && key != acted) {
      if (state == "retry" && last["attempts"].get<int>() >= 3)
        return fail("a capture failed its quality check three times");
      http.Post("/api/sim/button", R"({"button": "main"})", "application/json");
      acted = key;
    }
    if (ms_since(t0) > timeout_s * 1000.0)
      return fail("the session took over " + std::to_string(static_cast<int>(timeout_s)) + " s");
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
}

}  // namespace fb::cli
