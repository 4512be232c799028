// A real faceboothd for the sync tests: its data folder, a short session captured headless
// (three guide expressions, eight frames a take, synthetic camera), then the daemon serving HTTP
// on a loopback port with a token, as a child process the test can stop or SIGKILL.
#pragma once

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <httplib.h>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "tests/common/run_command.hpp"

extern char** environ;

namespace fb::test {

namespace fs = std::filesystem;

// A port nothing listens on right now (the kernel's choice for a socket bound to port 0).
inline int free_port() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
  socklen_t len = sizeof a;
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len);
  ::close(fd);
  return ntohs(a.sin_port);
}

// A child process with its output in a log file; killed (SIGKILL) when still running at the end.
class ChildProcess {
 public:
  ChildProcess() = default;
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;
  ~ChildProcess() { kill(SIGKILL); }

  bool start(const std::vector<std::string>& args, const fs::path& log) {
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 1, log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
    posix_spawn_file_actions_adddup2(&actions, 1, 2);
    std::vector<char*> argv;
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    const int rc = posix_spawn(&pid_, argv[0], &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    if (rc != 0) pid_ = -1;
    return rc == 0;
  }
  bool running() const { return pid_ > 0; }
  // Sends `signal` and reaps the child; returns its wait status (-1 when none was running).
  int kill(int signal) {
    if (pid_ <= 0) return -1;
    ::kill(pid_, signal);
    return wait();
  }
  int wait() {
    int status = -1;
    if (pid_ > 0) ::waitpid(pid_, &status, 0);
    pid_ = -1;
    return status;
  }
  // The exit code once it ended by itself, or nullopt while it runs.
  std::optional<int> poll() {
    int status = 0;
    if (pid_ <= 0 || ::waitpid(pid_, &status, WNOHANG) != pid_) return std::nullopt;
    pid_ = -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }

 private:
  pid_t pid_ = -1;
};

class Booth {
 public:
  Booth(fs::path dir, std::string camera, std::string token, std::string bind = "127.0.0.1",
        int captures = 3)
      : dir_(std::move(dir)), port_(free_port()) {
    fs::create_directories(dir_);
    // The project's first guide expressions, so the host rigs with its own recipes.
    std::ifstream in(fs::path(FB_DATA_DIR) / "guide_expressions.json");
    auto guide = nlohmann::json::parse(in);
    guide["expressions"].erase(guide["expressions"].begin() + captures, guide["expressions"].end());
    std::ofstream(dir_ / "guide.json") << guide.dump(1);
    std::ofstream(dir_ / "faceboothd.toml")
        << "[camera]\nuri = \"" << camera
        << "\"\ncapture_frames = 8\nrealtime = false\npreview_fps = 0\n"
        << "[storage]\ndata_dir = \"" << (dir_ / "data").string() << "\"\n"
        << "[http]\nbind = \"" << bind << "\"\nport = " << port_ << "\ntoken = \"" << token
        << "\"\n[session]\nguide_file = \"" << (dir_ / "guide.json").string() << "\"\n";
  }
  ~Booth() { daemon_.kill(SIGKILL); }

  // One complete session, headless (no HTTP); returns faceboothd's JSON (session id, store).
  nlohmann::json capture(const std::string& subject) {
    const auto run = run_command(std::string(FB_FACEBOOTHD) + " --config " +
                                     (dir_ / "faceboothd.toml").string() +
                                     " --run-session-headless --subject " + subject,
                                 Stderr::kToLog);
    if (run.exit_code != 0) return nullptr;
    return nlohmann::json::parse(run.out, nullptr, false);
  }
  // Serves HTTP until stop()/kill(); true once /api/status answers.
  bool start() {
    if (!daemon_.start({FB_FACEBOOTHD, "--config", (dir_ / "faceboothd.toml").string()},
                       dir_ / "faceboothd.log"))
      return false;
    httplib::Client http("127.0.0.1", port_);
    for (int i = 0; i < 600; ++i) {
      if (auto r = http.Get("/api/status"); r && r->status == 200) return true;
      if (!daemon_.running() || daemon_.poll()) return false;
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    return false;
  }
  void kill() { daemon_.kill(SIGKILL); }
  void stop() { daemon_.kill(SIGTERM); }
  int port() const { return port_; }
  std::string url() const { return "http://127.0.0.1:" + std::to_string(port_); }
  const fs::path& dir() const { return dir_; }
  fs::path store() const { return dir_ / "data" / "store"; }

 private:
  fs::path dir_;
  int port_;
  ChildProcess daemon_;
};

}  // namespace fb::test
