// facebooth-lab bench daemon: starts a real faceboothd (synthetic camera, simulated buttons),
// measures start-to-ready and resident memory, then runs a session while a second process hammers
// the HTTP API on loopback, and reports the frames the frame loop dropped. One JSON object on
// stdout, progress on stderr.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <thread>

#include "algo/core/clock.hpp"
#include "algo/core/result.hpp"
#include "host/cli/scratch_directory.hpp"
#include "sim/lab/daemon_harness.hpp"
#include "sim/lab/lab_commands.hpp"

// httplib last: its <resolv.h> defines `_res`, which breaks Eigen headers included after it.
#include <httplib.h>

namespace fb::cli {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// Tracking mode after the session: the daemon tracks the session's subject and streams VMC to
// a UDP socket here on loopback.
struct TrackingRun {
  double seconds = 0;
  long long frames = 0, datagrams_sent = 0, datagrams_received = 0, detections = 0;
  double latency_median_ms = 0, latency_p95_ms = 0, track_ms_median = 0, rss_peak = 0;
  std::string state, identity, reacquire;
};

struct SessionRun {
  double start_to_ready_ms = 0, daemon_ready_ms = 0, landmark_load_ms = 0;
  double rss_idle = 0, rss_peak = 0, rss_end = 0;
  long long frames_dropped = 0, frames_total = 0, captures = 0, load_requests = 0;
  double session_s = 0, export_wait_ms = 0, stop_ms = 0;
  bool clean_exit = false;
  CameraLog camera;  // the synthetic camera's real-time takes (late frames, buffer memory)
  std::optional<TrackingRun> tracking;
};

// One daemon from start to SIGTERM: a session of the configured captures, with `load_threads`
// HTTP clients in a second process (0 = no load). SIGTERM is sent once the session's end-of-
// session export has been written (stop_ms: the stop of a daemon at rest), or with
// `stop_during_export` as soon as the session is complete, while that export runs.
Result<SessionRun> run_daemon_session(const fs::path& daemon, const fs::path& dir, int port,
                                      int load_threads, bool stop_during_export,
                                      int track_seconds = 0, const UdpCounter* vmc = nullptr) {
  SessionRun out;
  fs::remove_all(dir / "data");
  const auto t0 = Clock::now();
  auto spawned = spawn_daemon(daemon, dir / "faceboothd.toml", dir / "faceboothd.log");
  if (!spawned) return spawned.failure();
  const pid_t pid = *spawned;
  Child daemon_proc(pid);
  httplib::Client http("127.0.0.1", port);
  http.set_read_timeout(10, 0);
  auto status = [&] { return daemon_status(http); };
  auto ready = wait_until_ready(http, t0);
  if (!ready) return fail(ready.error().message + "; see " + (dir / "faceboothd.log").string());
  out.start_to_ready_ms = *ready;
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  out.rss_idle = rss_mb(pid, "VmRSS:");
  // The daemon loads the landmark model before it reports ready; say so only if it did.
  const json ready_status = status();
  out.landmark_load_ms =
      ready_status.is_null() ? 0.0 : ready_status["stages"].value("landmark_model_load_ms", 0.0);

  std::cerr << "bench daemon: ready in " << out.start_to_ready_ms << " ms; "
            << (load_threads > 0 ? "loading the API with " + std::to_string(load_threads) +
                                       " clients while running the session"
                                 : std::string("running the session without HTTP load"))
            << "\n";
  pid_t load_pid = -1;
  if (load_threads > 0) {
    load_pid = ::fork();
    if (load_pid == 0) run_load(port, load_threads, dir / "load-count");
  }
  Child load(load_pid);
  const auto session_t0 = Clock::now();
  auto session = drive_session(http, "bench");
  if (!session) return session.failure();
  json last = *session;
  out.session_s = ms_since(session_t0) / 1000.0;
  // "complete" is published before the session's export folder is written.
  const auto export_t0 = Clock::now();
  while (!stop_during_export && !last.contains("last_export") && ms_since(export_t0) < 60000) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    last = status();
    if (last.is_null()) return fail("faceboothd stopped answering");
  }
  out.export_wait_ms = ms_since(export_t0);
  out.rss_peak = rss_mb(pid, "VmHWM:");
  out.rss_end = rss_mb(pid, "VmRSS:");
  if (load_threads > 0) {
    load.kill(SIGKILL);
    std::ifstream(dir / "load-count") >> out.load_requests;
  }
  out.frames_dropped = last["frames_dropped"];
  out.frames_total = last["frames_total"];
  out.captures = last["done_count"];
  out.daemon_ready_ms = last.value("start_to_ready_ms", 0.0);

  if (track_seconds > 0 && vmc != nullptr) {
    std::cerr << "bench daemon: tracking mode for " << track_seconds << " s\n";
    TrackingRun t;
    const long long received_before = vmc->received();
    http.Post("/api/mode", R"({"mode": "tracking"})", "application/json");
    const auto track_t0 = Clock::now();
    std::this_thread::sleep_for(std::chrono::seconds(track_seconds));
    const json s = status();
    if (s.is_null()) return fail("faceboothd stopped answering in tracking mode");
    const json& tr = s["tracking"];
    t.seconds = ms_since(track_t0) / 1000.0;
    t.frames = tr.value("frames", 0LL);
    t.datagrams_sent = tr.value("vmc_datagrams", 0LL);
    t.latency_median_ms = tr["latency_ms"].value("median", 0.0);
    t.latency_p95_ms = tr["latency_ms"].value("p95", 0.0);
    t.track_ms_median = tr.value("track_ms_median", 0.0);
    t.state = tr.value("state", "");
    t.identity = tr.value("identity", "");
    t.reacquire = tr.value("reacquire", "");
    t.detections = tr.value("detections", 0LL);
    t.rss_peak = rss_mb(pid, "VmHWM:");
    http.Post("/api/mode", R"({"mode": "capture"})", "application/json");
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    t.datagrams_received = vmc->received() - received_before;
    out.tracking = t;
  }

  const auto stop_t0 = Clock::now();
  const int exit_status = daemon_proc.kill(SIGTERM);
  out.stop_ms = ms_since(stop_t0);
  out.clean_exit = WIFEXITED(exit_status) && WEXITSTATUS(exit_status) == 0;
  out.camera = read_camera_log(dir / "faceboothd.log");
  return out;
}

// The daemon's log lives in the scratch folder, which goes at the end; --keep-logs copies it out
// (each take's frames missed and the camera's late frames are there).
void keep_log(const fs::path& dir, const fs::path& keep_dir, const std::string& label) {
  if (keep_dir.empty()) return;
  std::error_code ec;
  fs::create_directories(keep_dir, ec);
  fs::copy_file(dir / "faceboothd.log", keep_dir / ("faceboothd-" + label + ".log"),
                fs::copy_options::overwrite_existing, ec);
  if (ec)
    std::cerr << "bench daemon: cannot keep the log in " << keep_dir << ": " << ec.message()
              << "\n";
}

int bench_daemon(const ParsedOptions& o) {
  const fs::path daemon = find_daemon(o.get("daemon"));
  if (daemon.empty())
    return report_failure(
        {"faceboothd not found in the build tree, next to facebooth-lab or in /usr/bin; pass "
         "--daemon"});
  auto captures = o.get_int("captures");
  auto frames = o.get_int("frames");
  auto threads = o.get_int("load-threads");
  auto track_seconds = o.get_int("track-seconds");
  if (!captures || !frames || !threads || !track_seconds)
    return report_failure({"bad numeric option"});
  if (*track_seconds < 0 || *track_seconds > 600)
    return report_failure({"--track-seconds must be 0..600"});
  if (*captures < 1 || *captures > 20) return report_failure({"--captures must be 1..20"});
  if (*threads < 1) return report_failure({"--load-threads must be at least 1"});

  auto scratch = ScratchDirectory::create("facebooth-bench-daemon-");
  if (!scratch) return report_failure(scratch.error());
  const fs::path dir = scratch->path();

  // The first N guide expressions keep the bench short; takes are real time (paced at 30 fps).
  {
    std::ifstream in(fs::path(FB_DATA_DIR) / "guide_expressions.json");
    json guide = json::parse(in, nullptr, false);
    if (guide.is_discarded()) return report_failure({"cannot read data/guide_expressions.json"});
    guide["expressions"] = json(
        std::vector<json>(guide["expressions"].begin(), guide["expressions"].begin() + *captures));
    std::ofstream(dir / "guide.json") << guide.dump();
  }
  const int port = free_port();
  UdpCounter vmc;
  if (vmc.port() <= 0) return report_failure({"cannot open a UDP socket on loopback"});
  std::ofstream(dir / "faceboothd.toml")
      << "[camera]\nuri = \"synthetic:seed=7\"\ncapture_frames = " << *frames
      << "\nrealtime = true\npreview_fps = 5.0\n[storage]\ndata_dir = \"" << (dir / "data").string()
      << "\"\n[http]\nport = " << port << "\n[session]\nguide_file = \""
      << (dir / "guide.json").string() << "\"\n[streaming]\nvmc_target = \"127.0.0.1:" << vmc.port()
      << "\"\n";

  // The same session twice: without load (the frames the frame loop drops by itself; SIGTERM
  // while the end-of-session export runs) and under load (the figures; SIGTERM at rest).
  std::cerr << "bench daemon: starting " << daemon << " on port " << port << " (no load)\n";
  auto quiet = run_daemon_session(daemon, dir, port, 0, /*stop_during_export=*/true);
  if (!quiet) return report_failure(quiet.error());
  keep_log(dir, o.get("keep-logs"), "no-load");
  std::cerr << "bench daemon: starting " << daemon << " on port " << port << " (under load)\n";
  auto loaded = run_daemon_session(daemon, dir, port, static_cast<int>(*threads), false,
                                   static_cast<int>(*track_seconds), &vmc);
  if (!loaded) return report_failure(loaded.error());
  keep_log(dir, o.get("keep-logs"), "under-load");
  const SessionRun& r = *loaded;

  json out = {
      {"start_to_ready_ms", r.start_to_ready_ms},
      {"daemon_reported_ready_ms", r.daemon_ready_ms},
      // Peak resident memory over start-up and the session (VmHWM), landmark model
      // and face model loaded: what the 256 MB budget is about.
      {"rss_mb", r.rss_peak},
      {"rss_peak_mb", r.rss_peak},
      {"rss_peak_mb_without_load", quiet->rss_peak},
      {"rss_idle_mb", r.rss_idle},
      {"rss_end_mb", r.rss_end},
      {"rss_budget_mb", 256},
      {"landmark_model_loaded", r.landmark_load_ms > 0},
      {"landmark_model_load_ms", r.landmark_load_ms},
      {"frames_dropped_under_load", r.frames_dropped},
      {"frames_total", r.frames_total},
      {"frames_dropped_without_load", quiet->frames_dropped},
      {"frames_total_without_load", quiet->frames_total},
      {"camera_frames_late", r.camera.late},
      {"camera_frames_late_without_load", quiet->camera.late},
      {"camera_takes_logged", r.camera.takes + quiet->camera.takes},
      // The synthetic camera renders ahead inside the daemon's process: its slots are
      // lab memory in the daemon's RSS. The daemon's own peak is rss_mb minus this.
      {"camera_buffer_mb_max", std::max(r.camera.buffer_mb_max, quiet->camera.buffer_mb_max)},
      {"rss_peak_mb_less_camera_buffer",
       r.rss_peak - std::max(r.camera.buffer_mb_max, quiet->camera.buffer_mb_max)},
      {"frames_dropped_note",
       "takes arrive on the sensor's 30 fps clock (the synthetic camera renders ahead on "
       "its own thread, realtime=1); a frame is dropped when the daemon's frame loop "
       "reads it after the next one arrived (a gap in the stream's index, as with the "
       "freenect backend). camera_frames_late counts frames the renderer delivered after "
       "their sensor time: when it is 0 the drop figures measure the daemon alone"},
      {"captures", r.captures},
      {"frames_per_capture", *frames},
      {"session_s", r.session_s},
      {"session_s_without_load", quiet->session_s},
      {"export_wait_ms", r.export_wait_ms},
      {"load_clients", *threads},
      {"load_requests", r.load_requests},
      {"load_requests_per_s", r.load_requests / r.session_s},
      {"stop_ms", r.stop_ms},
      {"stop_ms_during_export", quiet->stop_ms},
      {"clean_exit", r.clean_exit && quiet->clean_exit}};
  if (r.tracking) {
    const TrackingRun& t = *r.tracking;
    out["tracking"] = {
        {"seconds", t.seconds},
        {"frames", t.frames},
        {"fps", t.seconds > 0 ? t.frames / t.seconds : 0.0},
        {"state", t.state},
        {"identity", t.identity},
        {"reacquire", t.reacquire},
        {"detections", t.detections},
        {"latency_ms_median", t.latency_median_ms},
        {"latency_ms_p95", t.latency_p95_ms},
        {"track_ms_median", t.track_ms_median},
        {"vmc_datagrams_sent", t.datagrams_sent},
        {"vmc_datagrams_received", t.datagrams_received},
        {"rss_peak_mb", t.rss_peak},
        {"note",
         "the daemon's tracking mode on the session's subject, depth only, VMC to a UDP socket "
         "on loopback; latency: from the frame leaving the camera driver (the synthetic camera "
         "renders it on the frame loop first) to its VMC datagrams sent, median and p95 over "
         "the last 300 frames; track_ms: the tracker's own share"}};
  }
  std::cout << out.dump(2) << "\n";
  return kExitOk;
}

}  // namespace

std::vector<Command> daemon_bench_commands() {
  return {{{"bench daemon",
            "faceboothd start-to-ready, memory, frames dropped under HTTP load, tracking latency",
            "Starts faceboothd (synthetic camera, simulated buttons, real-time takes) in a scratch "
            "directory, runs a session through its HTTP API while a second process loads the API "
            "from several keep-alive clients, then stops it with SIGTERM. rss_mb is the peak "
            "resident memory (VmHWM) with the dlib landmark model and the face model loaded, "
            "takes fused, landmarked, fitted and stored (budget 256 MB); rss_idle_mb is after "
            "start-up, rss_end_mb after the session. The session runs twice, first without "
            "load: frames_dropped_without_load is what the frame loop drops by itself. Then "
            "(--track-seconds) the daemon tracks the session's subject in tracking mode, "
            "streaming VMC to a UDP socket of this process: tracking.latency_ms_median / _p95 "
            "from the frame leaving the camera driver to its datagrams sent, the datagrams "
            "received, the peak memory while tracking.",
            {{"json", "", "print the JSON result (always on; for symmetry with other benches)", ""},
             {"daemon", "PATH", "the faceboothd binary", ""},
             {"captures", "N", "guide expressions to capture (1-20)", "5"},
             {"frames", "N", "frames per take (90 = 3 s at 30 fps)", "90"},
             {"load-threads", "N", "concurrent HTTP clients of the load process", "4"},
             {"track-seconds", "N",
              "then track the session's subject in tracking mode for N s (0 = skip)", "15"},
             {"keep-logs", "DIR", "copy the daemon's logs of both runs into DIR", ""}}},
           &bench_daemon}};
}

}  // namespace fb::cli
