// facebooth-lab bench sync: booths (real faceboothd processes, synthetic camera, headless
// sessions) on loopback and `facebooth sync` into a fresh host store: the transfer rate (checks
// and import included, no rigging) beside a plain HTTP GET of the same bundles (the peer: what
// the wire and the booth's export give), and sessions per minute with rigging and rig upload.
// One JSON object on stdout, progress on stderr.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "algo/core/clock.hpp"
#include "algo/core/result.hpp"
#include "sim/lab/lab_commands.hpp"

// httplib last: its <resolv.h> defines `_res`, which breaks Eigen headers included after it.
#include <httplib.h>

namespace fb::cli {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// A binary of the build tree next to facebooth-lab (build/sim/), or installed in /usr/bin.
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

// A loopback port nothing listens on now (the kernel's pick for port 0, released at once).
int loopback_port() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t len = sizeof a;
  int port = -1;
  if (fd >= 0 && ::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0 &&
      ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len) == 0)
    port = ntohs(a.sin_port);
  if (fd >= 0) ::close(fd);
  return port;
}

// A faceboothd serving HTTP; SIGTERM at the end.
class BoothDaemon {
 public:
  BoothDaemon() = default;
  BoothDaemon(const BoothDaemon&) = delete;
  BoothDaemon& operator=(const BoothDaemon&) = delete;
  ~BoothDaemon() {
    if (pid_ > 0) {
      ::kill(pid_, SIGTERM);
      ::waitpid(pid_, nullptr, 0);
    }
  }
  Result<void> start(const fs::path& daemon, const fs::path& config, int port) {
    pid_ = ::fork();
    if (pid_ < 0) return fail("fork failed");
    if (pid_ == 0) {
      const std::string log = (config.parent_path() / "faceboothd.log").string();
      std::freopen(log.c_str(), "a", stderr);
      std::freopen("/dev/null", "w", stdout);
      ::execl(daemon.c_str(), daemon.c_str(), "--config", config.c_str(), nullptr);
      std::_Exit(127);
    }
    httplib::Client http("127.0.0.1", port);
    http.set_connection_timeout(1, 0);
    http.set_read_timeout(5, 0);
    for (int i = 0; i < 600; ++i) {
      if (auto r = http.Get("/api/status"); r && r->status == 200) return success();
      if (::waitpid(pid_, nullptr, WNOHANG) == pid_) {
        pid_ = -1;
        break;  // it exited (a port in use, a bad config): the log says why
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    return fail("faceboothd never answered; see " +
                (config.parent_path() / "faceboothd.log").string());
  }

 private:
  pid_t pid_ = -1;
};

struct Run {
  int exit_code = -1;
  std::string out;
};
Run run(const std::string& command) {
  Run r;
  std::unique_ptr<FILE, int (*)(FILE*)> pipe(::popen(command.c_str(), "r"), ::pclose);
  if (!pipe) return r;
  char buf[4096];
  for (std::size_t n; (n = std::fread(buf, 1, sizeof buf, pipe.get())) > 0;) r.out.append(buf, n);
  const int status = ::pclose(pipe.release());
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

// The peer: every ready session's bundle fetched with a plain GET, booths in parallel.
Result<std::pair<std::uint64_t, double>> raw_get(const std::vector<int>& ports) {
  std::vector<std::uint64_t> bytes(ports.size(), 0);
  std::vector<std::string> errors(ports.size());
  const auto t0 = Clock::now();
  {
    std::vector<std::jthread> threads;
    for (std::size_t i = 0; i < ports.size(); ++i)
      threads.emplace_back([&, i] {
        httplib::Client http("127.0.0.1", ports[i]);
        http.set_read_timeout(60, 0);
        auto ready = http.Get("/api/offload/ready");
        if (!ready || ready->status != 200) return void(errors[i] = "no ready list");
        const json list = json::parse(ready->body, nullptr, false);
        if (list.is_discarded() || !list["sessions"].is_array())
          return void(errors[i] = "the ready list is not JSON");
        for (const auto& s : list["sessions"]) {
          auto tar = http.Get("/api/offload/sessions/" + std::to_string(s["id"].get<int>()) +
                              "/bundle.tar");
          if (!tar || tar->status != 200) return void(errors[i] = "bundle GET failed");
          bytes[i] += tar->body.size();
        }
      });
  }
  const double s = seconds_since(t0);
  std::uint64_t total = 0;
  for (std::size_t i = 0; i < ports.size(); ++i) {
    if (!errors[i].empty())
      return fail("plain GET from booth " + std::to_string(i) + ": " + errors[i]);
    total += bytes[i];
  }
  return std::pair{total, s};
}

int bench_sync(const ParsedOptions& o) {
  const fs::path daemon =
      find_binary(o.get("daemon"), "../firmware/daemon/faceboothd", "faceboothd");
  const fs::path host_tool = find_binary(o.get("facebooth"), "../host/cli/facebooth", "facebooth");
  if (daemon.empty() || host_tool.empty())
    return report_failure(
        {"faceboothd or facebooth not found next to facebooth-lab, in the build "
         "tree or in /usr/bin; pass --daemon and --facebooth"});
  auto booths = o.get_int("booths");
  auto sessions = o.get_int("sessions");
  auto captures = o.get_int("captures");
  auto frames = o.get_int("frames");
  if (!booths || !sessions || !captures || !frames) return report_failure({"bad numeric option"});
  if (*booths < 1 || *booths > 8 || *sessions < 1 || *captures < 2 || *captures > 20 || *frames < 8)
    return report_failure({"--booths 1..8, --sessions >= 1, --captures 2..20, --frames >= 8"});

  const fs::path dir =
      fs::temp_directory_path() / ("facebooth-bench-sync-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  struct Cleanup {
    fs::path dir;
    ~Cleanup() {
      std::error_code ec;
      fs::remove_all(dir, ec);
    }
  } cleanup{dir};
  json guide;
  {
    std::ifstream in(fs::path(FB_DATA_DIR) / "guide_expressions.json");
    guide = json::parse(in, nullptr, false);
    if (guide.is_discarded()) return report_failure({"cannot read data/guide_expressions.json"});
    guide["expressions"] = json(
        std::vector<json>(guide["expressions"].begin(), guide["expressions"].begin() + *captures));
  }
  std::vector<std::unique_ptr<BoothDaemon>> daemons;
  std::vector<int> ports;
  std::string booth_args;
  for (int b = 0; b < *booths; ++b) {
    const fs::path bd = dir / ("booth-" + std::to_string(b));
    fs::create_directories(bd);
    std::ofstream(bd / "guide.json") << guide.dump();
    const int port = loopback_port();
    std::ofstream(bd / "faceboothd.toml")
        << "[camera]\nuri = \"synthetic:seed=" << 5 + b << "\"\ncapture_frames = " << *frames
        << "\nrealtime = false\npreview_fps = 0\n[storage]\ndata_dir = \"" << (bd / "data").string()
        << "\"\n[http]\nport = " << port << "\n[session]\nguide_file = \""
        << (bd / "guide.json").string() << "\"\n";
    for (int s = 0; s < *sessions; ++s) {
      std::cerr << "bench sync: booth " << b << ", session " << s + 1 << " (headless)\n";
      auto r = run(daemon.string() + " --config " + (bd / "faceboothd.toml").string() +
                   " --run-session-headless --subject b" + std::to_string(b) + "s" +
                   std::to_string(s) + " 2>>" + (bd / "faceboothd.log").string());
      if (r.exit_code != 0)
        return report_failure(
            {"a headless session failed; see " + (bd / "faceboothd.log").string()});
    }
    daemons.push_back(std::make_unique<BoothDaemon>());
    if (auto ok = daemons.back()->start(daemon, bd / "faceboothd.toml", port); !ok)
      return report_failure(ok.error());
    ports.push_back(port);
    booth_args += " --booth http://127.0.0.1:" + std::to_string(port);
  }

  auto peer = raw_get(ports);
  if (!peer) return report_failure(peer.error());
  auto sync = [&](const std::string& store, const std::string& extra) -> Result<json> {
    std::cerr << "bench sync: facebooth sync" << extra << "\n";
    auto r =
        run(host_tool.string() + " sync --store " + (dir / store).string() + booth_args + extra);
    auto j = json::parse(r.out, nullptr, false);
    if (r.exit_code != 0 || j.is_discarded()) return fail("facebooth sync failed: " + r.out);
    return j;
  };
  auto transfer = sync("host-transfer", " --no-rig");
  if (!transfer) return report_failure(transfer.error());
  auto rigged = sync("host-rigged", "");
  if (!rigged) return report_failure(rigged.error());
  const double mb = (*transfer)["downloaded_bytes"].get<double>() / 1e6;
  const double sync_s = (*transfer)["seconds"].get<double>();
  const double raw_s = peer->second;
  const int total_sessions = static_cast<int>(*booths * *sessions);
  const double rigged_s = (*rigged)["seconds"].get<double>();
  json out = {{"booths", *booths},
              {"sessions_per_booth", *sessions},
              {"captures_per_session", *captures},
              {"frames_per_capture", *frames},
              {"bundle_mb_total", mb},
              {"sync_mb_per_s", mb / sync_s},
              {"sync_s", sync_s},
              {"peer",
               "plain HTTP GET of the same bundles (cpp-httplib, booths in parallel, no "
               "checks, nothing stored)"},
              {"peer_mb_per_s", static_cast<double>(peer->first) / 1e6 / raw_s},
              {"peer_s", raw_s},
              {"sync_vs_peer", sync_s > 0 ? raw_s / sync_s : 0.0},
              {"sessions", total_sessions},
              {"sessions_imported_rigged_uploaded", (*rigged)["rigs_uploaded"]},
              {"sync_with_rigging_s", rigged_s},
              {"sessions_per_min", total_sessions / rigged_s * 60.0},
              {"note",
               "loopback; sync_s is sync's own round (download, SHA-256 checks, decode, one "
               "SQLite transaction per session), without the process start and face model load; "
               "sync_vs_peer = peer_s / sync_s (1 = as fast as a plain GET); sessions_per_min "
               "includes example-based rigging (the session's captures) and the rig upload"}};
  std::cout << out.dump(2) << "\n";
  return kExitOk;
}

}  // namespace

std::vector<Command> sync_bench_commands() {
  return {{{"bench sync",
            "facebooth sync over loopback: MB/s beside a plain GET, sessions/min with rigging",
            "Captures --sessions headless sessions on each of --booths faceboothd processes "
            "(synthetic camera, the first --captures guide expressions, --frames frames a take), "
            "serves them on loopback, fetches every bundle once with a plain HTTP GET (the peer), "
            "then runs `facebooth sync --no-rig` into a fresh host store (sync_mb_per_s) and "
            "`facebooth sync` into another (sessions_per_min: import, rigging, rig upload).",
            {{"json", "", "print the JSON result (always on)", ""},
             {"daemon", "PATH", "the faceboothd binary", ""},
             {"facebooth", "PATH", "the facebooth binary", ""},
             {"booths", "N", "booths syncing in parallel", "2"},
             {"sessions", "N", "sessions per booth", "2"},
             {"captures", "N", "guide expressions per session (2-20)", "3"},
             {"frames", "N", "frames per take", "8"}}},
           &bench_sync}};
}

}  // namespace fb::cli
