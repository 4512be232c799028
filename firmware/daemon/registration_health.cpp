#include "firmware/daemon/registration_health.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

#include "firmware/daemon/frame_spool.hpp"
#include "firmware/daemon/status_figures.hpp"

namespace fb {
namespace {

nlohmann::json check_json(const RegistrationCheck& c) {
  if (!c.valid) return nullptr;
  nlohmann::json j = {{"misregistration_px", finite_or_zero(c.misregistration_px)},
                      {"residual_px", finite_or_zero(c.residual_px)},
                      {"confidence", finite_or_zero(c.confidence)},
                      {"confident", c.confident},
                      {"frames", c.frames},
                      {"samples", c.samples},
                      {"from", c.from}};
  if (!c.why.empty()) j["why"] = c.why;
  return j;
}

}  // namespace

const char* to_string(RegistrationVerdict verdict) {
  switch (verdict) {
    case RegistrationVerdict::kOff:
      return "off";
    case RegistrationVerdict::kChecking:
      return "checking";
    case RegistrationVerdict::kOk:
      return "ok";
    case RegistrationVerdict::kNeedsCalibration:
      return "needs_calibration";
  }
  return "?";
}

nlohmann::json to_json(const RegistrationStatus& s) {
  const RegistrationCheck& d = s.decisive;
  nlohmann::json j = {
      {"state", to_string(s.verdict)},
      {"needs_calibration", s.verdict == RegistrationVerdict::kNeedsCalibration},
      // The figures that decide the verdict (null until a confident estimate exists).
      {"misregistration_px",
       d.valid ? nlohmann::json(finite_or_zero(d.misregistration_px)) : nullptr},
      {"residual_px", d.valid ? nlohmann::json(finite_or_zero(d.residual_px)) : nullptr},
      {"confidence", d.valid ? nlohmann::json(finite_or_zero(d.confidence)) : nullptr},
      {"measured_on", d.valid ? nlohmann::json(d.from) : nullptr},
      {"limit_px", s.limit_px},
      {"checks", s.checks},
      {"last_check", check_json(s.last)},
      {"calibration",
       {{"source", s.calibration_source},
        {"note", s.calibration_note},
        {"dx_px", finite_or_zero(s.correction.dx_px)},
        {"dy_px", finite_or_zero(s.correction.dy_px)},
        {"rotation_deg", finite_or_zero(s.correction.rotation_deg)}}},
      {"message", s.message},
  };
  return j;
}

RegistrationHealth::RegistrationHealth(const KinectCalibration& calibration, std::string source,
                                       std::string note, RegistrationAdvice advice,
                                       RegistrationHealthOptions options, Listener on_change)
    : options_(options), advice_(std::move(advice)), on_change_(std::move(on_change)) {
  status_.limit_px = options_.max_misregistration_px;
  status_.calibration_source = std::move(source);
  status_.calibration_note = std::move(note);
  status_.correction = calibration.correction;
  if (!options_.enabled) {
    status_.verdict = RegistrationVerdict::kOff;
    return;
  }
  SelfCalibrationOptions o;
  o.max_frames = options_.frames_per_check;
  calibrator_ = std::make_unique<SelfCalibrator>(calibration, o);
  status_.message = advice_text({});
  thread_ = std::thread([this] { run(); });
}

RegistrationHealth::~RegistrationHealth() {
  {
    std::lock_guard lock(slot_mutex_);
    stopping_ = true;
  }
  slot_cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void RegistrationHealth::offer(const RgbdFrame& frame) {
  if (!options_.enabled || frame.depth_mm.empty() || frame.color.empty()) return;
  std::unique_lock lock(slot_mutex_, std::try_to_lock);
  if (!lock.owns_lock() || slot_full_) return;
  const auto now = std::chrono::steady_clock::now();
  if (now - last_taken_ < options_.min_frame_interval) return;
  last_taken_ = now;
  // Same-size assignment reuses the vectors' storage.
  slot_depth_ = frame.depth_mm;
  slot_color_ = frame.color;
  slot_generation_ = generation_.load();
  slot_full_ = true;
  lock.unlock();
  slot_cv_.notify_one();
}

void RegistrationHealth::run() {
  while (true) {
    std::uint64_t generation;
    {
      std::unique_lock lock(slot_mutex_);
      slot_cv_.wait(lock, [&] { return slot_full_ || stopping_; });
      if (stopping_) return;
      // Swapping keeps both buffer pairs allocated: no allocation per frame.
      std::swap(slot_depth_, work_depth_);
      std::swap(slot_color_, work_color_);
      generation = slot_generation_;
      slot_full_ = false;
    }
    add_and_maybe_estimate(work_depth_, work_color_, generation);
  }
}

void RegistrationHealth::add_and_maybe_estimate(const DepthImage& depth, const ColorImage& color,
                                                std::uint64_t generation) {
  Result<SelfCalibrationResult> estimate = fail("no estimate");
  {
    std::lock_guard lock(calibrator_mutex_);
    // A frame taken under a calibration that has since been replaced measures the old one.
    if (generation != generation_.load()) return;
    calibrator_->add_frame(depth, color);
    if (calibrator_->frames() < options_.frames_per_check) return;
    estimate = calibrator_->estimate();
    calibrator_->clear();
  }
  publish(estimate, "live frames");
}

Result<RegistrationCheck> RegistrationHealth::check_take(FrameSpool& spool,
                                                         const std::string& from) {
  if (!options_.enabled) return fail("the registration check is off");
  const std::size_t n = spool.size();
  if (n == 0) return fail("the take has no stored frames to check the registration on");
  const std::size_t k =
      std::min<std::size_t>(n, static_cast<std::size_t>(options_.frames_per_check));
  Result<SelfCalibrationResult> estimate = fail("no estimate");
  {
    std::lock_guard lock(calibrator_mutex_);
    calibrator_->clear();  // live frames gathered so far are dropped: the take decides now
    for (std::size_t j = 0; j < k; ++j) {
      if (auto ok = spool.read(j * n / k, spool_frame_); !ok) return ok.failure();
      calibrator_->add_frame(spool_frame_.depth_mm, spool_frame_.color);
    }
    estimate = calibrator_->estimate();
    calibrator_->clear();
  }
  publish(estimate, from);
  std::lock_guard lock(status_mutex_);
  return status_.last;
}

void RegistrationHealth::publish(const Result<SelfCalibrationResult>& estimate,
                                 const std::string& from) {
  RegistrationCheck c;
  c.from = from;
  if (estimate) {
    c.valid = true;
    c.confident = estimate->ok;
    c.misregistration_px = estimate->misregistration_px;
    c.residual_px = estimate->residual_px;
    c.confidence = estimate->confidence;
    c.frames = estimate->frames;
    c.samples = estimate->samples;
    c.why = estimate->why;
  } else {
    c.why = estimate.error().message;
  }
  RegistrationStatus copy;
  {
    std::lock_guard lock(status_mutex_);
    ++status_.checks;
    status_.last = c;
    // Only a confident estimate changes the verdict: a scene without depth edges (an empty
    // room) says nothing about the registration.
    if (c.valid && c.confident && std::isfinite(c.misregistration_px)) {
      status_.decisive = c;
      status_.verdict = c.misregistration_px > options_.max_misregistration_px
                            ? RegistrationVerdict::kNeedsCalibration
                            : RegistrationVerdict::kOk;
    }
    status_.message = advice_text(
        status_.verdict == RegistrationVerdict::kChecking ? status_.last : status_.decisive);
    copy = status_;
  }
  if (on_change_) on_change_(copy);
}

void RegistrationHealth::recalibrated(const KinectCalibration& calibration, std::string source,
                                      std::string note) {
  RegistrationStatus copy;
  {
    std::lock_guard lock(calibrator_mutex_);
    ++generation_;
    if (options_.enabled) {
      SelfCalibrationOptions o;
      o.max_frames = options_.frames_per_check;
      calibrator_ = std::make_unique<SelfCalibrator>(calibration, o);
    }
    std::lock_guard status_lock(status_mutex_);
    status_.calibration_source = std::move(source);
    status_.calibration_note = std::move(note);
    status_.correction = calibration.correction;
    if (options_.enabled) {
      status_.verdict = RegistrationVerdict::kChecking;
      status_.decisive = {};
      status_.last = {};
      status_.message = advice_text({});
    }
    copy = status_;
  }
  {
    std::lock_guard lock(slot_mutex_);
    slot_full_ = false;  // a frame waiting in the slot was taken under the old calibration
  }
  if (on_change_) on_change_(copy);
}

RegistrationStatus RegistrationHealth::status() const {
  std::lock_guard lock(status_mutex_);
  return status_;
}

bool RegistrationHealth::needs_calibration() const {
  std::lock_guard lock(status_mutex_);
  return status_.verdict == RegistrationVerdict::kNeedsCalibration;
}

// Called with status_mutex_ held (reads status_.verdict).
std::string RegistrationHealth::advice_text(const RegistrationCheck& check) const {
  switch (status_.verdict) {
    case RegistrationVerdict::kOff:
    case RegistrationVerdict::kOk:
      return "";
    case RegistrationVerdict::kChecking:
      if (check.valid && !check.why.empty())
        return "Checking the camera's registration: " + check.why +
               ". Put a person (or objects with clear outlines) 0.5-2 m in front of it.";
      return "Checking the camera's registration: it needs a few frames with a person (or "
             "objects with clear outlines) in view.";
    case RegistrationVerdict::kNeedsCalibration:
      break;
  }
  return "The camera needs calibration: its depth and colour images are " +
         fixed_or_zero(check.misregistration_px) + " px apart (limit " +
         fixed_or_zero(options_.max_misregistration_px) + " px, confidence " +
         fixed_or_zero(check.confidence, 2) +
         "), so landmarks would land on the wrong depth and fitted faces would be distorted; "
         "no session is fitted until it is calibrated. Let the booth self-calibrate: with a "
         "person (or objects with clear outlines) 0.5-2 m in front of the camera, press "
         "\"Calibrate camera\" on the kiosk page (POST " +
         advice_.self_calibrate_endpoint +
         "). Or calibrate it with a checkerboard: facebooth camera calibrate --camera " +
         advice_.camera_uri + " --board 9x6:25mm --out " + advice_.store_path +
         ", then restart faceboothd.";
}

}  // namespace fb
