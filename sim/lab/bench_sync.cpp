// facebooth-lab bench sync: booths (real faceboothd processes, synthetic camera, headless
// sessions) on loopback and `facebooth sync` into a fresh host store: the transfer rate (checks
// and import included, no rigging) beside a plain HTTP GET of the same bundles (the peer: what
// the wire and the booth's export give), and sessions per minute with rigging and rig upload.
// One JSON object on stdout, progress on stderr.
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
#include "host/cli/scratch_directory.hpp"
#include "sim/lab/daemon_harness.hpp"
#include "sim/lab/lab_commands.hpp"

// httplib last: its <resolv.h> defines `_res`, which breaks Eigen headers included after it.
#include <httplib.h>

namespace fb::cli {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

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
  const fs::path daemon = find_daemon(o.get("daemon"));
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

  auto scratch = ScratchDirectory::create("facebooth-bench-sync-");
  if (!scratch) return report_failure(scratch.error());
  const fs::path dir = scratch->path();
  json guide;
  {
    std::ifstream in(fs::path(FB_DATA_DIR) / "guide_expressions.json");
    guide = json::parse(in, nullptr, false);
    if (guide.is_discarded()) return report_failure({"cannot read data/guide_expressions.json"});
    guide["expressions"] = json(
        std::vector<json>(guide["expressions"].begin(), guide["expressions"].begin() + *captures));
  }
  std::vector<std::unique_ptr<Child>> daemons;  // serving HTTP, killed at the end
  std::vector<int> ports;
  std::string booth_args;
  for (int b = 0; b < *booths; ++b) {
    const fs::path bd = dir / ("booth-" + std::to_string(b));
    fs::create_directories(bd);
    std::ofstream(bd / "guide.json") << guide.dump();
    const int port = free_port();
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
    const auto started = Clock::now();
    auto spawned = spawn_daemon(daemon, bd / "faceboothd.toml", bd / "faceboothd-serving.log");
    if (!spawned) return report_failure(spawned.error());
    daemons.push_back(std::make_unique<Child>(*spawned));
    httplib::Client http("127.0.0.1", port);
    http.set_read_timeout(5, 0);
    if (auto ready = wait_until_ready(http, started); !ready)
      return report_failure(
          {ready.error().message + "; see " + (bd / "faceboothd-serving.log").string()});
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
