// Registration health: how far the camera's depth-to-colour registration is off, measured
// continuously from the frames faceboothd already gets (preview, takes, tracking), and the
// verdict the daemon acts on (status, kiosk page, LED, refusing to fit).
//
// A unit whose registration is off by more than a few pixels lifts every landmark to the wrong
// depth and every fit downstream distorts (issue 34): such a camera must be calibrated before
// a session is fitted. The measurement is algo/sensor's SelfCalibrator on a few frames at a
// time, on a thread of its own so the frame loop only copies a frame now and then.
//
//   RegistrationHealth health(calibration, context, options, on_change);
//   health.offer(frame);                 // worker: cheap, never blocks, drops when busy
//   health.check_take(spool, "capture 2");  // fit thread: the take's own frames, now
//   if (health.needs_calibration()) ...  // refuse to fit
//   health.recalibrated(new_calibration, source, note);  // after self-calibration
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>

#include "algo/core/frame.hpp"
#include "algo/core/result.hpp"
#include "algo/sensor/kinect_calibration.hpp"
#include "algo/sensor/self_calibration.hpp"

namespace fb {

class FrameSpool;

struct RegistrationHealthOptions {
  bool enabled = true;
  double max_misregistration_px = 3.0;  // over this, with confidence: needs calibration
  int frames_per_check = 8;             // frames per estimate (a colour gradient is ~1.2 MB)
  // Frames are taken at most this often: enough for a verdict within seconds at preview
  // rates, without competing with fusion for the CPU during a take.
  std::chrono::milliseconds min_frame_interval{150};
};

// What the user is told to do; filled in by the daemon (its camera and its store's path).
struct RegistrationAdvice {
  std::string camera_uri;
  std::string store_path;  // where a checkerboard device.json for this unit goes
  std::string self_calibrate_endpoint = "/api/camera/self-calibrate";
};

enum class RegistrationVerdict {
  kOff,               // [camera] registration_check = false
  kChecking,          // no confident estimate yet under the current calibration
  kOk,                // within the limit
  kNeedsCalibration,  // over the limit: sessions are not fitted
};
const char* to_string(RegistrationVerdict verdict);

// One estimate.
struct RegistrationCheck {
  bool valid = false;      // an estimate exists
  bool confident = false;  // the estimator's ok (enough samples, agreeing halves)
  double misregistration_px = 0;
  double residual_px = 0;
  double confidence = 0;
  int frames = 0;
  int samples = 0;
  std::string from;  // "live frames" or "capture 2 of session 5"
  std::string why;   // when not confident: what was missing
};

struct RegistrationStatus {
  RegistrationVerdict verdict = RegistrationVerdict::kChecking;
  RegistrationCheck decisive;  // the latest confident estimate: it decides the verdict
  RegistrationCheck last;      // the latest estimate, confident or not
  long long checks = 0;
  double limit_px = 3.0;
  std::string calibration_source;     // "defaults", "device", "stored", "self-calibration"
  std::string calibration_note;       // e.g. the stored file
  RegistrationCorrection correction;  // the current calibration's registration correction
  std::string message;                // what is wrong and what to do; "" when healthy
};
nlohmann::json to_json(const RegistrationStatus& status);

class RegistrationHealth {
 public:
  using Listener = std::function<void(const RegistrationStatus&)>;

  // Starts the checker thread (none when options.enabled is false). `on_change` is called after
  // every estimate and recalibration, without any of this object's locks held.
  RegistrationHealth(const KinectCalibration& calibration, std::string source, std::string note,
                     RegistrationAdvice advice, RegistrationHealthOptions options,
                     Listener on_change);
  ~RegistrationHealth();
  RegistrationHealth(const RegistrationHealth&) = delete;
  RegistrationHealth& operator=(const RegistrationHealth&) = delete;

  // Frame loop: hands the frame to the checker when it is free and the last frame taken is
  // older than min_frame_interval. Copies into a buffer of the same size (no allocation once
  // sized) under a try-lock: never blocks the caller.
  void offer(const RgbdFrame& frame);

  // Checks a recorded take's frames now, on the caller's thread (the fit thread): up to
  // frames_per_check frames spread over the spool. Publishes the estimate like any other.
  Result<RegistrationCheck> check_take(FrameSpool& spool, const std::string& from);

  // The camera now delivers frames under `calibration`: frames and the verdict measured under
  // the old one are forgotten.
  void recalibrated(const KinectCalibration& calibration, std::string source, std::string note);

  RegistrationStatus status() const;
  bool needs_calibration() const;
  const RegistrationHealthOptions& options() const { return options_; }

 private:
  void run();
  void add_and_maybe_estimate(const DepthImage& depth, const ColorImage& color,
                              std::uint64_t generation);
  void publish(const Result<SelfCalibrationResult>& estimate, const std::string& from);
  std::string advice_text(const RegistrationCheck& check) const;

  const RegistrationHealthOptions options_;
  const RegistrationAdvice advice_;
  Listener on_change_;

  // The hand-over slot between the frame loop and the checker thread.
  std::mutex slot_mutex_;
  std::condition_variable slot_cv_;
  DepthImage slot_depth_, work_depth_;
  ColorImage slot_color_, work_color_;
  bool slot_full_ = false;
  std::uint64_t slot_generation_ = 0;
  std::chrono::steady_clock::time_point last_taken_{};
  bool stopping_ = false;

  // The estimator, shared by the checker thread and check_take().
  std::mutex calibrator_mutex_;
  std::unique_ptr<SelfCalibrator> calibrator_;
  std::atomic<std::uint64_t> generation_{0};  // bumped by recalibrated()
  RgbdFrame spool_frame_;                     // check_take's read buffer

  mutable std::mutex status_mutex_;
  RegistrationStatus status_;

  std::thread thread_;
};

}  // namespace fb
