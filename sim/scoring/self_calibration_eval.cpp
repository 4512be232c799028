#include "sim/scoring/self_calibration_eval.hpp"
#include "algo/core/clock.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "algo/sensor/self_calibration.hpp"
#include "host/cli/stats.hpp"
#include "sim/camera/synthetic_camera.hpp"
#include "storage/asset_files.hpp"

namespace fb::cli {
namespace {

struct UnitTake {
  std::vector<RgbdFrame> frames;
  KinectCalibration reported;
  KinectCalibration truth;
  double distance_mm = 700.0;
};

// Where the pipeline puts a depth pixel in colour against where it truly lands, the largest
// over the image centre and the quadrant centres, for a surface at `z_mm` (the face's depth).
// End to end: the pipeline reads the raw disparity with its own depth law, so a depth-law
// error moves the parallax and is part of the registration error at that depth.
double registration_error_px(const KinectCalibration& estimated, const KinectCalibration& truth,
                             double z_mm) {
  const KinectRegistration est(estimated), tru(truth);
  const auto z = static_cast<std::uint16_t>(std::lround(z_mm));
  const std::uint16_t raw = tru.mm_to_raw(z);
  const std::uint16_t z_read = est.raw_to_mm(raw);
  double worst = 0.0;
  for (const auto& [x, y] : {std::pair{320, 240}, {160, 120}, {480, 120}, {160, 360}, {480, 360}}) {
    double tx = 0, ty = 0, ex = 0, ey = 0;
    if (!tru.depth_to_color(x, y, z, tx, ty) || !est.depth_to_color(x, y, z_read, ex, ey)) continue;
    worst = std::max(worst, std::hypot(ex - tx, ey - ty));
  }
  return worst;
}

std::string unit_uri(std::uint64_t unit, int frames, const std::string& extra) {
  // Subjects, distances and turns vary with the unit so no two units see the same scene.
  const int distance = 600 + static_cast<int>(unit % 5) * 100;
  return "seed=" + std::to_string(unit) + ",unit=" + std::to_string(unit) +
         ",frames=" + std::to_string(frames) + ",distance=" + std::to_string(distance) +
         (extra.empty() ? "" : "," + extra);
}

Result<UnitTake> render_unit(const FaceModel& model, std::uint64_t unit, int frames,
                             const std::string& extra) {
  auto options = parse_synthetic_options(unit_uri(unit, frames, extra), model);
  if (!options) return options.failure();
  auto camera = make_synthetic_camera(model, *options);
  if (!camera) return camera.failure();
  if (auto started = (*camera)->start(); !started) return started.failure();
  UnitTake take;
  take.reported = (*camera)->info().calibration;
  take.truth = options->calibration;
  take.distance_mm = options->distance_mm;
  take.frames.resize(static_cast<std::size_t>(frames));
  for (auto& frame : take.frames) {
    auto got = (*camera)->next_frame(frame, std::chrono::milliseconds(1000));
    if (!got) return got.failure();
  }
  return take;
}

}  // namespace

Result<nlohmann::ordered_json> evaluate_self_calibration(const SelfCalibrationEvalOptions& options,
                                                         const std::function<void(int)>& progress) {
  auto model = load_face_model();
  if (!model) return fail("eval calibration: cannot load the face model: " + model.error().message);
  std::vector<double> errors;
  int ok = 0, wrongly_ok = 0;
  nlohmann::ordered_json rows = nlohmann::ordered_json::array();
  nlohmann::ordered_json not_ok = nlohmann::ordered_json::array();
  for (int u = 0; u < options.units; ++u) {
    const std::uint64_t unit = options.first_unit + static_cast<std::uint64_t>(u);
    auto take = render_unit(*model, unit, options.frames, options.extra_uri);
    if (!take) return take.failure();
    SelfCalibrator calibrator(take->reported);
    for (const auto& frame : take->frames) calibrator.add_frame(frame.depth_mm, frame.color);
    auto r = calibrator.estimate();
    if (!r) return r.failure();
    const KinectCalibration estimated = with_registration(take->reported, r->correction);
    const double error = registration_error_px(estimated, take->truth, take->distance_mm);
    const auto& t = take->truth.correction;
    rows.push_back(
        {{"unit", unit},
         {"ok", r->ok},
         {"error_px", error},
         {"offset_px", registration_error_px(take->reported, take->truth, take->distance_mm)},
         {"dx_error_px", r->correction.dx_px - t.dx_px},
         {"dy_error_px", r->correction.dy_px - t.dy_px},
         {"rotation_error_deg", r->correction.rotation_deg - t.rotation_deg},
         {"true_depth_scale", t.depth_scale},
         {"residual_px", r->residual_px},
         {"confidence", r->confidence}});
    if (r->ok) {
      ++ok;
      errors.push_back(error);
      if (error > 3.0) ++wrongly_ok;
    } else {
      not_ok.push_back({{"unit", unit}, {"why", r->why}, {"error_px", error}});
    }
    if (progress) progress(u + 1);
  }
  double mean = 0.0;
  for (double e : errors) mean += e;
  nlohmann::ordered_json j;
  j["units"] = options.units;
  j["frames_per_unit"] = options.frames;
  j["self_calibration_units_ok"] = ok;
  j["self_calibration_residual_px_p95"] = percentile(errors, 0.95);
  j["self_calibration_residual_px_mean"] = errors.empty() ? 0.0 : mean / errors.size();
  j["self_calibration_residual_px_max"] =
      errors.empty() ? 0.0 : *std::max_element(errors.begin(), errors.end());
  j["self_calibration_wrongly_ok"] = wrongly_ok;
  j["self_calibration_not_ok"] = std::move(not_ok);
  j["self_calibration_units"] = std::move(rows);
  return j;
}

namespace {

// The peer: chamfer matching with OpenCV, the registration check test's measure, searched
// exhaustively over integer shifts (no rotation).
cv::Point2d opencv_chamfer_shift(const std::vector<RgbdFrame>& frames,
                                 const KinectRegistration& registration, int radius) {
  std::vector<double> score(static_cast<std::size_t>((2 * radius + 1) * (2 * radius + 1)), 0.0);
  DepthImage registered;
  for (const auto& frame : frames) {
    registration.register_depth_to_color(frame.depth_mm, registered);
    cv::Mat rgb(frame.color.height, frame.color.width, CV_8UC3,
                const_cast<Rgb8*>(frame.color.pixels.data()));
    cv::Mat grey, edges, dist;
    cv::cvtColor(rgb, grey, cv::COLOR_RGB2GRAY);
    cv::GaussianBlur(grey, grey, cv::Size(5, 5), 1.2);
    cv::Canny(grey, edges, 50, 150);
    cv::distanceTransform(edges == 0, dist, cv::DIST_L2, cv::DIST_MASK_PRECISE);
    std::vector<cv::Point> points;
    for (int y = 10; y < registered.height - 10; ++y)
      for (int x = 10; x < registered.width - 10; ++x) {
        const int z = registered.at(x, y);
        if (z == 0) continue;
        for (const auto& [ox, oy] : {std::pair{1, 0}, {-1, 0}, {0, 1}, {0, -1}}) {
          int q = 0;
          for (int k = 1; k <= 8 && q == 0; ++k) q = registered.at(x + k * ox, y + k * oy);
          if (q != 0 && q - z > std::max(25, z * 4 / 100)) {
            points.emplace_back(x, y);
            break;
          }
        }
      }
    for (int dy = -radius; dy <= radius; ++dy)
      for (int dx = -radius; dx <= radius; ++dx) {
        double sum = 0.0;
        for (const auto& p : points) {
          const int x = p.x + dx, y = p.y + dy;
          sum += (x < 0 || y < 0 || x >= dist.cols || y >= dist.rows)
                     ? 15.0
                     : std::min(dist.at<float>(y, x), 15.0f);
        }
        score[static_cast<std::size_t>((dy + radius) * (2 * radius + 1) + dx + radius)] +=
            points.empty() ? 0.0 : sum / static_cast<double>(points.size());
      }
  }
  const auto best = std::min_element(score.begin(), score.end()) - score.begin();
  return {static_cast<double>(best % (2 * radius + 1) - radius),
          static_cast<double>(best / (2 * radius + 1) - radius)};
}

}  // namespace

Result<nlohmann::ordered_json> bench_self_calibration(int frames, std::uint64_t unit) {
  auto model = load_face_model();
  if (!model)
    return fail("bench calibration: cannot load the face model: " + model.error().message);
  auto take = render_unit(*model, unit, frames, "");
  if (!take) return take.failure();

  const auto t0 = Clock::now();
  SelfCalibrator calibrator(take->reported);
  for (const auto& frame : take->frames) calibrator.add_frame(frame.depth_mm, frame.color);
  auto r = calibrator.estimate();
  if (!r) return r.failure();
  const double ours_ms = ms_since(t0);

  const KinectRegistration registration(take->reported);
  const auto t1 = Clock::now();
  const cv::Point2d shift = opencv_chamfer_shift(take->frames, registration, 28);
  const double peer_ms = ms_since(t1);
  RegistrationCorrection peer;
  peer.dx_px = shift.x;  // the shift of the depth edges is the correction itself
  peer.dy_px = shift.y;

  nlohmann::ordered_json j;
  j["frames"] = frames;
  j["unit"] = unit;
  j["self_calibration_ms"] = ours_ms;
  const KinectCalibration estimated = with_registration(take->reported, r->correction);
  j["peer"] = "OpenCV chamfer (Canny + distanceTransform, exhaustive +-28 px shift search)";
  j["peer_ms"] = peer_ms;
  j["speedup_vs_peer"] = ours_ms > 0.0 ? peer_ms / ours_ms : 0.0;
  j["self_calibration_error_px"] = registration_error_px(estimated, take->truth, take->distance_mm);
  j["peer_error_px"] = registration_error_px(with_registration(take->reported, peer), take->truth,
                                             take->distance_mm);
  j["self_calibration_ok"] = r->ok;
  return j;
}

}  // namespace fb::cli
