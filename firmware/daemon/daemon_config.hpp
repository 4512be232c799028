// faceboothd's configuration: one TOML file (board/faceboothd.toml is the documented default),
// every key optional. Unknown keys are errors, so a typo never silently falls back to a default.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>

#include "algo/core/result.hpp"
#include "algo/fitting/fit_qa.hpp"
#include "drivers/gpio/gpio.hpp"

namespace fb {

struct CameraConfig {
  std::string uri = "synthetic:seed=1";
  int capture_frames = 90;   // frames per head-turn take: 3 s at 30 fps
  double preview_fps = 5.0;  // live preview rate while idle (the kiosk's picture)
  // Pace sources that do not pace themselves (synthetic) at the camera's frame rate, as a real
  // sensor would. Off makes takes as fast as the CPU allows (tests, headless demo).
  bool realtime = true;
  // With the synthetic camera, render the guide expression on the simulated subject, so each
  // take shows the expression asked for.
  bool synthetic_imitates_guide = true;
  // Keep every Nth frame of a take for the store (1 = all). A stored 640x480 frame is 1.5 MB
  // (colour + depth) and the store's API takes a capture's frames in one call, so they are held
  // until the quality check; 3 (30 of 90 frames, 46 MB) keeps the daemon, with the ~100 MB
  // landmark model, inside its 256 MB budget. Fusion uses every frame.
  int stored_frame_stride = 3;
  // Registration health (issue 34): how far depth and colour are apart, measured on the frames
  // the daemon already gets. Over max_misregistration_px (with confidence) the camera "needs
  // calibration" (status, page, LED) and sessions are not fitted.
  bool registration_check = true;
  double max_misregistration_px = 3.0;
  // Self-calibrate on its own when the check says the camera needs it (while idle, at most once
  // a minute), from self_calibrate_frames preview frames; POST /api/camera/self-calibrate does
  // the same on demand. A result is kept per unit under the data directory (calibration/).
  bool self_calibrate = false;
  int self_calibrate_frames = 45;
};

struct StorageConfig {
  std::filesystem::path data_dir;  // default: $STATE_DIRECTORY (systemd) or ./facebooth-data
};

struct HttpConfig {
  bool enabled = true;
  std::string bind = "127.0.0.1";
  int port = 8080;  // 0 = pick a free port (tests); the chosen one is in the status and log
  // Required from any client that is not on loopback (Authorization: Bearer TOKEN). Empty =
  // non-loopback clients are refused. token_file is read at start (systemd credentials).
  std::string token;
  std::filesystem::path token_file;
  int threads = 4;
};

struct SessionConfig {
  std::filesystem::path guide_file;  // default: guide_expressions.json in the data directory
  double min_coverage = 0.25;        // fused face-box pixels with depth / face-box pixels
  double max_residual_mm = 2.5;      // mean ICP point-to-plane RMS of the fused frames
  double min_fused_fraction = 0.6;   // fused frames / recorded frames
  bool resume = true;                // continue the newest incomplete session after a restart
  // After fusion: dlib landmarks on the frontal colour frame + the quick fit (neutral for the
  // first capture, expression fits from it for the others), folded into the quality check.
  bool quick_fit = true;
  std::filesystem::path shape_predictor = "/usr/share/dlib/shape_predictor_68_face_landmarks.dat";
  std::filesystem::path face_model;  // default: facemodel.fbfm in the data directory
  // The fit's QA limits (algo/fitting/fit_qa.hpp holds the defaults the host evaluates with).
  double max_fit_rms_mm = FitQaLimits{}.max_fit_rms_mm;
  double max_landmark_error_mm = FitQaLimits{}.max_landmark_error_mm;
  double min_landmark_score = -0.5;  // dlib's face detection margin
};

struct StreamingConfig {
  // Tracking mode sends VMC (OSC over UDP) to vmc_target, or osc_target when that is empty:
  // "host:port", "host" (port 39539) or ":port". Both empty = no streaming.
  std::string osc_target;
  std::string vmc_target;
  bool save_takes = true;       // store each tracking run as a take in the session store
  int max_take_frames = 18000;  // 10 min at 30 fps; longer runs keep the first part
};

struct DaemonConfig {
  CameraConfig camera;
  GpioOptions gpio;
  StorageConfig storage;
  HttpConfig http;
  SessionConfig session;
  StreamingConfig streaming;
  int watchdog_divisor = 3;  // ping systemd this many times per WatchdogSec
};

// Parses TOML text; `origin` names the source in errors. Relative paths are resolved against
// `base_dir`. Defaults are filled in (data dir from the environment when unset).
Result<DaemonConfig> parse_daemon_config(std::string_view toml_text, std::string_view origin,
                                         const std::filesystem::path& base_dir = {});
Result<DaemonConfig> load_daemon_config(const std::filesystem::path& path);
// The defaults, with the environment applied (STATE_DIRECTORY).
DaemonConfig default_daemon_config();
// Checks cross-field consistency (ports, frame counts, thresholds, readable guide file).
Result<void> validate_daemon_config(const DaemonConfig& config);
// The configuration as TOML (what --print-config shows; parses back to the same values).
std::string to_toml(const DaemonConfig& config);

}  // namespace fb
