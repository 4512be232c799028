// facebooth-lab bench soak: one real faceboothd runs N kiosk sessions back to back, with HTTP
// load on its API throughout and tracking mode between sessions, as a booth does over a day's
// work. Reports the resident memory's growth per session (a least-squares slope over the
// sessions after the first), open file descriptors and threads before and after, disk used per
// session, and every error. One JSON object on stdout, progress on stderr.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "algo/core/clock.hpp"
#include "host/cli/export_summary.hpp"
#include "host/cli/scratch_directory.hpp"
#include "sim/lab/daemon_harness.hpp"
#include "sim/lab/lab_commands.hpp"

// httplib last: its <resolv.h> defines `_res`, which breaks Eigen headers included after it.
#include <httplib.h>

namespace fb::cli {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// Where the daemon stands after one session (and its tracking interval).
struct Sample {
  int session = 0;
  double rss_mb = 0, seconds = 0;
  int fds = 0, threads = 0;
  double disk_mb = 0;
};

// Least-squares slope of y over x.
double slope(const std::vector<double>& x, const std::vector<double>& y) {
  const auto n = static_cast<double>(x.size());
  if (x.size() < 2) return 0.0;
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    sx += x[i];
    sy += y[i];
    sxx += x[i] * x[i];
    sxy += x[i] * y[i];
  }
  const double d = n * sxx - sx * sx;
  return d != 0.0 ? (n * sxy - sx * sy) / d : 0.0;
}

struct SoakSettings {
  int sessions = 50, captures = 2, frames = 30, load_threads = 2, track_seconds = 3;
};

void write_config(const fs::path& dir, int port, int vmc_port, const SoakSettings& s) {
  {
    std::ifstream in(fs::path(FB_DATA_DIR) / "guide_expressions.json");
    json guide = json::parse(in, nullptr, false);
    guide["expressions"] = json(
        std::vector<json>(guide["expressions"].begin(), guide["expressions"].begin() + s.captures));
    std::ofstream(dir / "guide.json") << guide.dump();
  }
  std::ofstream(dir / "faceboothd.toml")
      << "[camera]\nuri = \"synthetic:seed=11\"\ncapture_frames = " << s.frames
      << "\nrealtime = true\npreview_fps = 5.0\n[storage]\ndata_dir = \"" << (dir / "data").string()
      << "\"\n[http]\nport = " << port << "\n[session]\nguide_file = \""
      << (dir / "guide.json").string() << "\"\n[streaming]\nvmc_target = \"127.0.0.1:" << vmc_port
      << "\"\n";
}

// Tracking mode for `seconds`, then back to capture mode; fails when the mode never comes back.
Result<void> track_interval(httplib::Client& http, int seconds) {
  if (seconds <= 0) return success();
  http.Post("/api/mode", R"({"mode": "tracking"})", "application/json");
  std::this_thread::sleep_for(std::chrono::seconds(seconds));
  http.Post("/api/mode", R"({"mode": "capture"})", "application/json");
  for (int i = 0; i < 500; ++i) {
    const json s = daemon_status(http);
    if (!s.is_null() && s.value("state", "") == "idle") return success();
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return fail("faceboothd did not come back from tracking mode to idle within 10 s");
}

// Descriptors that stay: the fewest open over 1 s (ten looks). One look alone counts what is in
// flight at that moment (the load clients' connections, an export's files) and varied by +-2
// between sessions; a leak stays in every look.
int lasting_fds(pid_t pid) {
  int fewest = open_fds(pid);
  for (int i = 0; i < 9; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    fewest = std::min(fewest, open_fds(pid));
  }
  return fewest;
}

Result<SoakSettings> soak_settings(const ParsedOptions& o) {
  auto sessions = o.get_int("sessions");
  auto captures = o.get_int("captures");
  auto frames = o.get_int("frames");
  auto threads = o.get_int("load-threads");
  auto track = o.get_int("track-seconds");
  if (!sessions || !captures || !frames || !threads || !track) return fail("bad numeric option");
  if (*sessions < 3 || *sessions > 1000) return fail("--sessions must be 3..1000");
  if (*captures < 1 || *captures > 20) return fail("--captures must be 1..20");
  if (*frames < 10 || *frames > 300) return fail("--frames must be 10..300");
  if (*threads < 0 || *threads > 16) return fail("--load-threads must be 0..16");
  if (*track < 0 || *track > 60) return fail("--track-seconds must be 0..60");
  return SoakSettings{static_cast<int>(*sessions), static_cast<int>(*captures),
                      static_cast<int>(*frames), static_cast<int>(*threads),
                      static_cast<int>(*track)};
}

// The JSON result. The first session warms caches and pools (arenas, the landmark model's
// pages): the slope and the "before" figures start after it.
json soak_report(const SoakSettings& settings, const std::vector<Sample>& samples,
                 const std::vector<std::string>& errors, long long frames_dropped,
                 long long load_requests, double rss_peak_mb, double soak_s) {
  std::vector<double> x, y;
  for (std::size_t i = 1; i < samples.size(); ++i) {
    x.push_back(samples[i].session);
    y.push_back(samples[i].rss_mb);
  }
  const Sample& first = samples[1];
  const Sample& last = samples.back();
  json per_session = json::array();
  for (const auto& s : samples)
    per_session.push_back({{"session", s.session},
                           {"rss_mb", s.rss_mb},
                           {"fds", s.fds},
                           {"threads", s.threads},
                           {"disk_mb", s.disk_mb}});
  const json out = {
      {"sessions", settings.sessions},
      {"sessions_run", samples.size()},
      {"captures_per_session", settings.captures},
      {"frames_per_capture", settings.frames},
      {"rss_growth_mb_per_session", slope(x, y)},
      {"rss_growth_budget_mb_per_session", 0.5},
      {"rss_mb_after_first_session", first.rss_mb},
      {"rss_mb_at_end", last.rss_mb},
      {"rss_peak_mb", rss_peak_mb},
      {"fds_before", first.fds},
      {"fds_after", last.fds},
      {"fd_growth", last.fds - first.fds},
      {"threads_before", first.threads},
      {"threads_after", last.threads},
      {"thread_growth", last.threads - first.threads},
      {"disk_mb", last.disk_mb},
      {"disk_mb_per_session", last.disk_mb / static_cast<double>(samples.size())},
      {"frames_dropped", frames_dropped},
      {"load_clients", settings.load_threads},
      {"load_requests", load_requests},
      {"tracking_seconds_between_sessions", settings.track_seconds},
      {"soak_s", soak_s},
      {"errors", errors.size()},
      {"error_messages", errors},
      {"per_session", per_session},
      {"note",
       "before = after the first session (warm-up), after = after the last; "
       "rss_growth_mb_per_session is the least-squares slope of VmRSS over sessions 2..N"}};
  return out;
}

int bench_soak(const ParsedOptions& o) {
  const fs::path daemon = find_daemon(o.get("daemon"));
  if (daemon.empty())
    return report_failure(
        {"faceboothd not found in the build tree, next to facebooth-lab or in "
         "/usr/bin; pass --daemon"});
  auto parsed = soak_settings(o);
  if (!parsed) return report_failure(parsed.error());
  const SoakSettings settings = *parsed;

  auto scratch = ScratchDirectory::create("facebooth-bench-soak-");
  if (!scratch) return report_failure(scratch.error());
  const fs::path dir = scratch->path();
  const int port = free_port();
  UdpCounter vmc;
  if (port <= 0 || vmc.port() <= 0) return report_failure({"cannot open loopback sockets"});
  write_config(dir, port, vmc.port(), settings);

  const auto t0 = Clock::now();
  auto spawned = spawn_daemon(daemon, dir / "faceboothd.toml", dir / "faceboothd.log");
  if (!spawned) return report_failure(spawned.error());
  Child daemon_proc(*spawned);
  const pid_t pid = *spawned;
  httplib::Client http("127.0.0.1", port);
  http.set_read_timeout(10, 0);
  auto ready = wait_until_ready(http, t0);
  if (!ready) return report_failure(ready.error());
  pid_t load_pid = -1;
  if (settings.load_threads > 0) {
    load_pid = ::fork();
    if (load_pid == 0) run_load(port, settings.load_threads, dir / "load-count");
  }
  Child load(load_pid);

  std::vector<Sample> samples;
  std::vector<std::string> errors;
  long long frames_dropped = 0;
  const auto soak_t0 = Clock::now();
  for (int i = 0; i < settings.sessions; ++i) {
    auto last = drive_session(http, "soak-" + std::to_string(i), 300.0);
    if (!last) {
      errors.push_back("session " + std::to_string(i) + ": " + last.error().message);
      if (daemon_status(http).is_null()) break;  // the daemon is gone: nothing more to learn
      http.Post("/api/sim/button", R"({"button": "main"})", "application/json");  // error -> idle
    } else {
      frames_dropped = (*last).value("frames_dropped", 0LL);
    }
    if (auto ok = track_interval(http, settings.track_seconds); !ok)
      errors.push_back("session " + std::to_string(i) + ": " + ok.error().message);
    Sample s;
    s.session = i;
    s.seconds = ms_since(soak_t0) / 1000.0;
    s.rss_mb = rss_mb(pid, "VmRSS:");
    s.fds = lasting_fds(pid);
    s.threads = thread_count(pid);
    const auto bytes = folder_bytes(dir / "data");
    s.disk_mb = bytes ? static_cast<double>(*bytes) / (1024.0 * 1024.0) : -1.0;
    samples.push_back(s);
    std::cerr << "bench soak: session " << i + 1 << "/" << settings.sessions << ": RSS " << s.rss_mb
              << " MB, " << s.fds << " fds, " << s.threads << " threads, disk " << s.disk_mb
              << " MB, " << errors.size() << " errors\n";
  }
  long long load_requests = 0;
  if (load_pid > 0) {
    load.kill(SIGKILL);
    std::ifstream(dir / "load-count") >> load_requests;
  }
  const double rss_peak = rss_mb(pid, "VmHWM:");  // before the process is gone
  const int exit_status = daemon_proc.kill(SIGTERM);
  if (!(WIFEXITED(exit_status) && WEXITSTATUS(exit_status) == 0))
    errors.push_back("faceboothd did not exit cleanly on SIGTERM");
  if (samples.size() < 3) return report_failure({"fewer than 3 sessions ran: " + errors.front()});

  const json out = soak_report(settings, samples, errors, frames_dropped, load_requests, rss_peak,
                               ms_since(soak_t0) / 1000.0);
  std::cout << out.dump(2) << "\n";
  return errors.empty() ? kExitOk : kExitFailure;
}

}  // namespace

std::vector<Command> soak_bench_commands() {
  return {{{"bench soak",
            "faceboothd over a day's work: N sessions back to back under HTTP load",
            "Starts one faceboothd (synthetic camera, simulated buttons, real-time takes) in a "
            "scratch directory and runs --sessions kiosk sessions through its HTTP API, one "
            "after the other, while a second process loads the API; between sessions the "
            "daemon tracks the subject in tracking mode for --track-seconds. Reports the "
            "resident memory's growth per session (budget 0.5 MB), open file descriptors and "
            "threads after the first and after the last session, disk used, and every error "
            "(exit status 1 when there was one). 50 sessions take about 15 minutes.",
            {{"json", "", "print the JSON result (always on; for symmetry with other benches)", ""},
             {"daemon", "PATH", "the faceboothd binary", ""},
             {"sessions", "N", "sessions to run (3-1000)", "50"},
             {"captures", "N", "guide expressions per session (1-20)", "2"},
             {"frames", "N", "frames per take (30 = 1 s at 30 fps)", "30"},
             {"load-threads", "N", "concurrent HTTP clients of the load process (0 = none)", "2"},
             {"track-seconds", "N", "tracking mode between sessions, seconds (0 = skip)", "3"}}},
           &bench_soak}};
}

}  // namespace fb::cli
