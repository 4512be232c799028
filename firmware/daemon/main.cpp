// faceboothd: the facebooth device daemon (kiosk capture sessions, tracking mode, HTTP API).
//
//   faceboothd [--config FILE]                run as a service (systemd Type=notify)
//   faceboothd --check-config [--config FILE] validate and print the effective configuration
//   faceboothd --print-default-config         the defaults as TOML
//   faceboothd --run-session-headless [--config FILE] [--data-dir DIR] [--subject NAME]
//              [--frames N]                   one complete session with simulated button
//                                             presses; prints JSON with where it is stored
#include <malloc.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <string>
#include <vector>

#include "firmware/daemon/daemon.hpp"

namespace {

constexpr const char* kUsage =
    "usage: faceboothd [--config FILE] [--check-config] [--print-default-config]\n"
    "                  [--run-session-headless [--subject NAME] [--frames N]] [--data-dir DIR]\n"
    "                  [--port N]\n";

constexpr const char* kHelp =
    "\n"
    "The facebooth device daemon: kiosk capture sessions (20 guide expressions: record a 3 s\n"
    "head turn, fuse, landmarks, quick fit, quality check), tracking mode (VMC over OSC, live\n"
    "JSON), the HTTP API and kiosk page, buttons and LEDs.\n"
    "\n"
    "  --config FILE           TOML configuration (default: built-in defaults: synthetic camera,\n"
    "                          simulated GPIO, storage in $STATE_DIRECTORY or else\n"
    "                          ./facebooth-data, HTTP on 127.0.0.1:8080; see\n"
    "                          --print-default-config)\n"
    "  --check-config          validate the configuration, print the effective one, exit\n"
    "  --print-default-config  print the defaults as TOML and exit\n"
    "  --run-session-headless  run one complete session with simulated button presses, then\n"
    "                          exit; prints JSON with the session id, store and export folder\n"
    "  --subject NAME          subject name for --run-session-headless\n"
    "  --frames N              frames per take (default 90 = 3 s at 30 fps)\n"
    "  --data-dir DIR          storage folder (overrides [storage] data_dir)\n"
    "  --port N                HTTP port (overrides [http] port; 0 = any free port)\n"
    "\n"
    "Stops cleanly on SIGTERM/SIGINT; an unfinished session resumes at its next capture.\n";

int usage_error(const std::string& message) {
  std::cerr << "faceboothd: " << message << "\n" << kUsage;
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  // OpenBLAS (linked through dlib) starts its worker threads when the library loads, before
  // main() can block SIGTERM for them, and a stop signal delivered to such a thread kills the
  // process instead of reaching the daemon's signalfd. With one BLAS thread it starts none, so
  // re-execute once with that set (the systemd unit sets it already, so no re-exec there).
  if (std::getenv("OPENBLAS_NUM_THREADS") == nullptr) {
    ::setenv("OPENBLAS_NUM_THREADS", "1", 1);
    ::execv("/proc/self/exe", argv);
    // If that fails, carry on: everything works except a clean stop on SIGTERM.
  }
  // Memory (budget 256 MB peak with the landmark model): buffers of a take's size (frames,
  // depth maps, model bases) come from mmap and go back to the system when freed, instead of
  // fragmenting the heap and per-thread arenas; a fixed threshold also stops glibc from raising
  // it after the first large free.
  mallopt(M_MMAP_THRESHOLD, 128 * 1024);
  mallopt(M_ARENA_MAX, 2);
  std::vector<std::string> args(argv + 1, argv + argc);
  std::string config_path, data_dir, subject, frames, port;
  bool check = false, print_default = false, headless = false;
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    auto value = [&](std::string& out) {
      if (i + 1 >= args.size()) return false;
      out = args[++i];
      return true;
    };
    if (a == "--config") {
      if (!value(config_path)) return usage_error("--config needs a file");
    } else if (a == "--data-dir") {
      if (!value(data_dir)) return usage_error("--data-dir needs a directory");
    } else if (a == "--subject") {
      if (!value(subject)) return usage_error("--subject needs a name");
    } else if (a == "--frames") {
      if (!value(frames)) return usage_error("--frames needs a number");
    } else if (a == "--port") {
      if (!value(port)) return usage_error("--port needs a number");
    } else if (a == "--check-config") {
      check = true;
    } else if (a == "--print-default-config") {
      print_default = true;
    } else if (a == "--run-session-headless") {
      headless = true;
    } else if (a == "-h" || a == "--help") {
      std::cout << kUsage << kHelp;
      return 0;
    } else {
      return usage_error("unknown argument '" + a + "'");
    }
  }
  if (print_default) {
    std::cout << fb::to_toml(fb::default_daemon_config());
    return 0;
  }
  auto config = config_path.empty() ? fb::Result<fb::DaemonConfig>(fb::default_daemon_config())
                                    : fb::load_daemon_config(config_path);
  if (!config) {
    std::cerr << "faceboothd: " << config.error().message << "\n";
    return 1;
  }
  if (!data_dir.empty()) config->storage.data_dir = std::filesystem::absolute(data_dir);
  try {
    if (!frames.empty()) config->camera.capture_frames = std::stoi(frames);
    if (!port.empty()) config->http.port = std::stoi(port);
  } catch (const std::exception&) {
    return usage_error("--frames and --port take numbers");
  }
  if (headless) {
    // Headless: simulated buttons, takes as fast as the CPU allows, no HTTP unless configured
    // explicitly with a port on the command line.
    config->gpio.backend = "sim";
    config->camera.realtime = false;
    config->camera.preview_fps = 0;
    if (port.empty()) config->http.enabled = false;
  }
  if (auto ok = fb::validate_daemon_config(*config); !ok) {
    std::cerr << "faceboothd: " << ok.error().message << "\n";
    return 1;
  }
  if (check) {
    std::cout << fb::to_toml(*config);
    std::cerr << "faceboothd: configuration OK\n";
    return 0;
  }

  fb::DaemonOptions options;
  options.handle_signals = true;
  auto daemon = fb::Daemon::create(*config, options);
  if (!daemon) {
    std::cerr << "faceboothd: " << daemon.error().message << "\n";
    return 1;
  }
  if (headless) {
    auto result = (*daemon)->run_headless_session(subject);
    if (!result) {
      std::cerr << "faceboothd: headless session failed: " << result.error().message << "\n";
      return 1;
    }
    nlohmann::json j = {{"session", result->session_id},
                        {"store", result->store.string()},
                        {"session_folder", result->session_folder.string()},
                        {"export", result->export_folder.string()},
                        {"captures_done", result->captures_done},
                        {"retries", result->retries},
                        {"frames_total", result->frames_total},
                        {"frames_dropped", result->frames_dropped}};
    std::cout << j.dump(2) << "\n";
    return 0;
  }
  if (auto ok = (*daemon)->run(); !ok) {
    std::cerr << "faceboothd: " << ok.error().message << "\n";
    return 1;
  }
  return 0;
}
