// facebooth camera self-calibrate: the registration estimated from ordinary frames.
#include <chrono>
#include <iostream>

#include <nlohmann/json.hpp>

#include "algo/core/figure_text.hpp"
#include "algo/sensor/self_calibration.hpp"
#include "drivers/camera/common/calibrated_camera.hpp"
#include "drivers/camera/common/device_json.hpp"
#include "host/cli/commands.hpp"
#include "host/cli/frame_open.hpp"
#include "host/cli/progress.hpp"

namespace fb::cli {
namespace {

nlohmann::ordered_json result_json(const SelfCalibrationResult& r) {
  nlohmann::ordered_json j;
  j["ok"] = r.ok;
  if (!r.ok) j["why"] = r.why;
  j["dx_px"] = r.correction.dx_px;
  j["dy_px"] = r.correction.dy_px;
  j["rotation_deg"] = r.correction.rotation_deg;
  j["misregistration_px"] = r.misregistration_px;
  j["residual_px"] = r.residual_px;
  j["residual_px_p95"] = r.residual_px_p95;
  j["confidence"] = r.confidence;
  j["halves_disagreement_px"] = r.halves_disagreement_px;
  j["frames"] = r.frames;
  j["samples"] = r.samples;
  return j;
}

int run_self_calibrate(const ParsedOptions& options) {
  auto frames = options.get_int("frames");
  if (!frames) return report_failure(frames.error());
  if (*frames < 1) return report_failure({"--frames must be at least 1"});
  auto camera = open_started_camera(options.get("camera"));
  if (!camera) return report_failure(camera.error());
  const CameraInfo info = (*camera)->info();
  SelfCalibrator calibrator(info.calibration);
  RgbdFrame frame;
  const auto started = std::chrono::steady_clock::now();
  {
    Progress progress("reading frames", *frames);
    for (long long i = 0; i < *frames; ++i) {
      auto got = (*camera)->next_frame(frame, std::chrono::milliseconds(2000));
      if (!got) return report_failure(got.error());
      if (*got == FrameStatus::kEndOfStream) break;
      if (*got == FrameStatus::kTimeout) continue;
      calibrator.add_frame(frame.depth_mm, frame.color);
      progress.update(i + 1);
    }
  }
  auto result = calibrator.estimate();
  if (!result) return report_failure(result.error());
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  const KinectCalibration calibrated = with_registration(info.calibration, result->correction);
  const std::string key = calibration_key(info);

  if (options.flag("json")) {
    auto j = result_json(*result);
    j["camera"] = info.uri;
    j["unit_key"] = key;
    j["seconds"] = seconds;
    std::cout << j.dump(2) << "\n";
  } else {
    std::cout << "camera " << info.uri << ": " << result->frames << " frames, " << result->samples
              << " depth-edge samples\n"
              << "  registration correction: dx " << figure_text(result->correction.dx_px)
              << " px, dy " << figure_text(result->correction.dy_px) << " px, rotation "
              << figure_text(result->correction.rotation_deg) << " deg\n"
              << "  the calibration it started from was off by "
              << figure_text(result->misregistration_px) << " px\n"
              << "  residual after correction: median " << figure_text(result->residual_px)
              << " px, p95 " << figure_text(result->residual_px_p95) << " px; confidence "
              << figure_text(result->confidence) << "\n";
  }
  if (!result->ok) {
    return report_failure({"self-calibration of " + info.uri + " is not usable: " + result->why});
  }
  if (const auto out = options.get("out"); !out.empty()) {
    if (auto written = write_device_json(out, calibrated); !written)
      return report_failure(written.error());
    std::cerr << "wrote " << out << "\n";
  }
  if (options.flag("save")) {
    const auto store = CalibrationStore::user_default();
    if (auto saved = store.save(key, calibrated); !saved) return report_failure(saved.error());
    std::cerr << "saved for " << key << " in " << store.path_for(key).string()
              << "; the next run of this camera starts from it\n";
  }
  return kExitOk;
}

}  // namespace

std::vector<Command> self_calibration_commands() {
  return {
      {{"camera self-calibrate",
        "estimate the depth-to-colour registration of a Kinect unit from ordinary frames "
        "(depth silhouettes against colour edges)",
        "Use it on a unit without a device.json: any scene with objects in front of a background\n"
        "works, best a person moving a little. It prints the correction, how far the current\n"
        "calibration was off and the residual; --save keeps it for this unit (by serial or\n"
        "recording path, in $FACEBOOTH_CALIBRATION_DIR or ~/.local/state/facebooth/calibration)\n"
        "so later runs start from it. A checkerboard (`camera calibrate`) also fixes the depth "
        "law.",
        {{"camera", "URI", "camera to read from", "synthetic:"},
         {"frames", "N", "frames to read", "90"},
         {"out", "FILE", "also write the calibrated device.json here", ""},
         {"save", "", "keep the result for this unit", ""},
         {"json", "", "print the result as JSON", ""}}},
       run_self_calibrate},
  };
}

}  // namespace fb::cli
