// facebooth-lab eval self-calibration | bench calibration: self-calibration scored on seeded
// decalibrated synthetic units (sim/scoring/self_calibration_eval.hpp).
#include <iostream>

#include <nlohmann/json.hpp>

#include "algo/core/figure_text.hpp"
#include "host/cli/progress.hpp"
#include "sim/lab/lab_commands.hpp"
#include "sim/scoring/self_calibration_eval.hpp"

namespace fb::cli {
namespace {

int run_eval(const ParsedOptions& options) {
  auto units = options.get_int("units");
  if (!units) return report_failure(units.error());
  auto frames = options.get_int("frames");
  if (!frames) return report_failure(frames.error());
  if (*units < 1 || *frames < 1) return report_failure({"--units and --frames must be >= 1"});
  SelfCalibrationEvalOptions o;
  o.units = static_cast<int>(*units);
  o.frames = static_cast<int>(*frames);
  o.extra_uri = options.get("synthetic");
  auto j = [&] {
    Progress progress("self-calibrating units", o.units);
    return evaluate_self_calibration(o, [&](int done) { progress.update(done); });
  }();
  if (!j) return report_failure(j.error());
  if (options.flag("json")) {
    std::cout << j->dump(2) << "\n";
  } else {
    std::cout << "self-calibration: " << (*j)["self_calibration_units_ok"].get<int>() << " of "
              << o.units << " units ok; registration error p95 "
              << figure_text((*j)["self_calibration_residual_px_p95"].get<double>()) << " px, mean "
              << figure_text((*j)["self_calibration_residual_px_mean"].get<double>()) << " px; "
              << (*j)["self_calibration_wrongly_ok"].get<int>() << " wrongly ok\n";
  }
  return kExitOk;
}

int run_bench(const ParsedOptions& options) {
  auto frames = options.get_int("frames");
  if (!frames) return report_failure(frames.error());
  if (*frames < 1) return report_failure({"--frames must be at least 1"});
  auto j = bench_self_calibration(static_cast<int>(*frames), 17);
  if (!j) return report_failure(j.error());
  std::cout << j->dump(2) << "\n";
  return kExitOk;
}

}  // namespace

std::vector<Command> self_calibration_eval_commands() {
  return {
      {{"eval self-calibration",
        "score self-calibration on seeded decalibrated synthetic units against their truth",
        "Each unit (seed 1..N) is a Kinect whose registration is off by up to 20 px and 1 deg,\n"
        "seen through a head-turn take; the estimate is compared with the unit's true\n"
        "registration. A unit reported not ok is listed with why, never counted as calibrated.",
        {{"units", "N", "units to calibrate", "100"},
         {"frames", "N", "frames of each unit's take", "45"},
         {"synthetic", "KEYS", "extra synthetic camera keys for every take", ""},
         {"json", "", "print the figures as JSON", ""}}},
       run_eval},
      {{"bench calibration",
        "time self-calibration of one take against an OpenCV chamfer-matching peer",
        "One decalibrated synthetic unit; both read the same frames, rendering excluded.",
        {{"frames", "N", "frames of the take", "90"}, {"json", "", "JSON output (always)", ""}}},
       run_bench},
  };
}

}  // namespace fb::cli
