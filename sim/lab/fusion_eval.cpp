// facebooth-lab eval fusion: the face-box KinectFusion (algo/fusion) scored against the synthetic
// camera's ground truth (pose, fused depth) and run on the real dump. One JSON object on
// stdout, progress on stderr.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <numeric>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "host/cli/frame_png.hpp"
#include "host/cli/scratch_directory.hpp"
#include "host/cli/stats.hpp"
#include "sim/camera/world_presets.hpp"
#include "sim/lab/fusion_lab.hpp"

namespace fb::cli::fusion_lab {
namespace {

// Face region of the frontal frame: inside the convex hull of the 68 landmarks (brows to chin),
// where the noiseless rendering has surface, inside the face box.
cv::Mat face_region(const Sequence& seq, const PixelRect& box) {
  const PinholeIntrinsics& k = seq.intrinsics;
  cv::Mat mask = cv::Mat::zeros(k.height, k.width, CV_8U);
  std::vector<cv::Point> points;
  for (const auto& p : seq.frontal_landmarks_px)
    points.emplace_back(static_cast<int>(std::lround(p.x())), static_cast<int>(std::lround(p.y())));
  if (points.size() < 3) return mask;
  std::vector<cv::Point> hull;
  cv::convexHull(points, hull);
  cv::fillConvexPoly(mask, hull, cv::Scalar(255));
  for (int y = 0; y < k.height; ++y)
    for (int x = 0; x < k.width; ++x)
      if (!box.contains(x, y) || seq.frontal_noiseless.empty() ||
          seq.frontal_noiseless.at(x, y) <= 0.0f)
        mask.at<std::uint8_t>(y, x) = 0;
  return mask;
}

struct DepthErrors {
  double fused_mae_mm = 0, raw_mae_mm = 0, fill = 0, fused_p95_mm = 0, raw_p95_mm = 0;
  double fused_max_mm = 0, raw_max_mm = 0;
  double fused_bias_mm = 0, raw_bias_mm = 0;  // signed mean (measured - truth)
  int face_pixels = 0;
  cv::Mat fused_error, raw_error;  // CV_32F, NaN where no value
};

DepthErrors depth_errors(const Sequence& seq, const SurfaceView& fused, const cv::Mat& region) {
  DepthErrors e;
  const PinholeIntrinsics& k = seq.intrinsics;
  e.fused_error = cv::Mat(k.height, k.width, CV_32F, cv::Scalar(NAN));
  e.raw_error = cv::Mat(k.height, k.width, CV_32F, cv::Scalar(NAN));
  std::vector<double> fe, re;
  const DepthImage& raw = seq.depth[seq.frontal];
  for (int y = 0; y < k.height; ++y)
    for (int x = 0; x < k.width; ++x) {
      if (!region.at<std::uint8_t>(y, x)) continue;
      ++e.face_pixels;
      const double truth = seq.frontal_noiseless.at(x, y);
      if (const float d = fused.depth_mm.at(x, y); d > 0.0f) {
        fe.push_back(std::abs(d - truth));
        e.fused_bias_mm += d - truth;
        e.fused_error.at<float>(y, x) = static_cast<float>(d - truth);
      }
      if (const std::uint16_t d = raw.at(x, y); d > 0) {
        re.push_back(std::abs(d - truth));
        e.raw_bias_mm += d - truth;
        e.raw_error.at<float>(y, x) = static_cast<float>(d - truth);
      }
    }
  auto mean = [](const std::vector<double>& v) {
    return v.empty() ? 0.0 : std::accumulate(v.begin(), v.end(), 0.0) / v.size();
  };
  e.fused_bias_mm /= std::max<std::size_t>(fe.size(), 1);
  e.raw_bias_mm /= std::max<std::size_t>(re.size(), 1);
  e.fused_mae_mm = mean(fe);
  e.raw_mae_mm = mean(re);
  e.fused_p95_mm = percentile(fe, 0.95);
  e.raw_p95_mm = percentile(re, 0.95);
  e.fused_max_mm = fe.empty() ? 0.0 : *std::max_element(fe.begin(), fe.end());
  e.raw_max_mm = re.empty() ? 0.0 : *std::max_element(re.begin(), re.end());
  e.fill = e.face_pixels > 0 ? static_cast<double>(fe.size()) / e.face_pixels : 0.0;
  return e;
}

// Paper Fig. 2 style error map: |depth - truth| over the face, raw frame beside fused, with a
// shared mm colour bar. Pixels without a value are dark grey; outside the face, black.
Result<void> write_error_map(const std::filesystem::path& path, const DepthErrors& e,
                             const PixelRect& box, double scale_mm) {
  const int pad = 10;
  auto panel = [&](const cv::Mat& err, const std::string& title, double mae) {
    cv::Mat roi = err(cv::Rect(box.x0, box.y0, box.width(), box.height()));
    cv::Mat out(box.height(), box.width(), CV_8UC3, cv::Scalar(0, 0, 0));
    cv::Mat abs8(box.height(), box.width(), CV_8U, cv::Scalar(0));
    cv::Mat has(box.height(), box.width(), CV_8U, cv::Scalar(0));
    for (int y = 0; y < roi.rows; ++y)
      for (int x = 0; x < roi.cols; ++x) {
        const float v = roi.at<float>(y, x);
        if (std::isnan(v)) continue;
        abs8.at<std::uint8_t>(y, x) =
            static_cast<std::uint8_t>(std::clamp(std::abs(v) / scale_mm, 0.0, 1.0) * 255.0);
        has.at<std::uint8_t>(y, x) = 1;
      }
    cv::Mat colour;
    cv::applyColorMap(abs8, colour, cv::COLORMAP_JET);
    colour.copyTo(out, has);
    cv::Mat big;
    cv::resize(out, big, cv::Size(), 2.0, 2.0, cv::INTER_NEAREST);
    cv::Mat framed(big.rows + 30, big.cols, CV_8UC3, cv::Scalar(255, 255, 255));
    big.copyTo(framed(cv::Rect(0, 30, big.cols, big.rows)));
    char text[128];
    std::snprintf(text, sizeof text, "%s: mean %.2f mm", title.c_str(), mae);
    cv::putText(framed, text, cv::Point(4, 20), cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(0, 0, 0),
                1, cv::LINE_AA);
    return framed;
  };
  const cv::Mat raw = panel(e.raw_error, "raw frame", e.raw_mae_mm);
  const cv::Mat fused = panel(e.fused_error, "fused", e.fused_mae_mm);
  // Colour bar: 0 .. scale_mm, ticks every scale/4.
  const int bar_w = 70;
  cv::Mat bar(raw.rows, bar_w, CV_8UC3, cv::Scalar(255, 255, 255));
  const int top = 40, bottom = raw.rows - 20;
  for (int y = top; y <= bottom; ++y) {
    const double v = static_cast<double>(bottom - y) / (bottom - top);
    cv::Mat px(1, 1, CV_8U, cv::Scalar(static_cast<int>(v * 255.0)));
    cv::Mat c;
    cv::applyColorMap(px, c, cv::COLORMAP_JET);
    cv::line(bar, cv::Point(4, y), cv::Point(22, y), cv::Scalar(c.at<cv::Vec3b>(0, 0)), 1);
  }
  for (int t = 0; t <= 4; ++t) {
    const int y = bottom - (bottom - top) * t / 4;
    char label[32];
    std::snprintf(label, sizeof label, "%.1f%s", scale_mm * t / 4, t == 4 ? "+" : "");
    cv::putText(bar, label, cv::Point(26, y + 4), cv::FONT_HERSHEY_SIMPLEX, 0.4,
                cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  }
  cv::putText(bar, "mm", cv::Point(26, top - 12), cv::FONT_HERSHEY_SIMPLEX, 0.45,
              cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  cv::Mat row;
  cv::Mat gap(raw.rows, pad, CV_8UC3, cv::Scalar(255, 255, 255));
  cv::hconcat(std::vector<cv::Mat>{raw, gap, fused, gap, bar}, row);
  if (auto ok = cli::write_image_file(path, row); !ok) return ok.failure();
  return success();
}

Result<void> write_ply(const std::filesystem::path& path, const TriangleMesh& mesh) {
  std::ofstream out(path, std::ios::binary);
  if (!out) return fail("cannot write " + path.string() + " (check the directory exists)");
  out << "ply\nformat binary_little_endian 1.0\ncomment facebooth fused face (mm, first camera)\n"
      << "element vertex " << mesh.vertices.size()
      << "\nproperty float x\nproperty float y\nproperty float z\n"
      << "property float nx\nproperty float ny\nproperty float nz\n"
      << "element face " << mesh.triangles.size() << "\nproperty list uchar int vertex_indices\n"
      << "end_header\n";
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
    out.write(reinterpret_cast<const char*>(mesh.vertices[i].data()), 12);
    out.write(reinterpret_cast<const char*>(mesh.normals[i].data()), 12);
  }
  for (const auto& t : mesh.triangles) {
    const std::uint8_t n = 3;
    out.write(reinterpret_cast<const char*>(&n), 1);
    out.write(reinterpret_cast<const char*>(t.data()), 12);
  }
  if (!out) return fail("write error on " + path.string());
  return success();
}

// The replay directory of a dump given as a directory or a .tar.xz (extracted to `scratch`).
Result<std::filesystem::path> dump_directory(const std::filesystem::path& source,
                                             const std::filesystem::path& scratch) {
  if (std::filesystem::is_directory(source)) return source;
  if (!std::filesystem::exists(source))
    return fail("recording " + source.string() + " does not exist");
  const std::string cmd =
      "tar -xJf '" + source.string() + "' -C '" + scratch.string() + "' 2>/dev/null";
  if (std::system(cmd.c_str()) != 0)
    return fail("could not extract " + source.string() + " (needs tar with xz support)");
  for (const auto& entry : std::filesystem::directory_iterator(scratch))
    if (entry.is_directory()) return entry.path();
  return fail(source.string() + " holds no dump directory");
}

// One seed's run: its JSON entry and what the summary adds up.
struct SeedRun {
  nlohmann::json json;
  PoseErrors pose;
  DepthErrors depth;
  int lost = 0, dropped = 0;
};

// Fuses and scores one synthetic seed; the first (`first`) also writes the error map and the
// mesh its options ask for, and names them in `result`.
Result<SeedRun> eval_seed(const ParsedOptions& options, const std::string& world, int seed,
                          long long frames, int frontal, double scale,
                          const FusionOptions& fusion_options, FaceFusion& fusion,
                          std::optional<LandmarkDetector>& detector, bool first,
                          nlohmann::json& result) {
  std::string base = options.get("synthetic");
  if (!world.empty()) base += (base.ends_with(":") ? "" : ",") + ("world=" + world);
  const std::string uri = synthetic_uri(base, seed, frames);
  std::cerr << "eval fusion: " << uri << " ...\n";
  auto seq = load_sequence(uri, frames, frontal);
  if (!seq) return seq.failure();
  if (seq->camera_from_model.empty() || seq->frontal_noiseless.empty())
    return fail("camera '" + uri + "' has no ground truth; use a synthetic URI");
  auto choice = choose_box(options.get("box"), *seq, detector);
  if (!choice) return choice.failure();
  auto run = run_fusion(fusion, *seq, choice->box, fusion_options, options.flag("verbose"),
                        options.flag("truth-poses"));
  if (!run) return run.failure();
  const PoseErrors pe = pose_errors(*seq, *run, options.flag("verbose"));
  const RigidPose frontal_pose = run->reports[seq->frontal].world_from_camera;
  const SurfaceView view = fusion.render(frontal_pose);
  // Scored inside the box the frontal frame was fused in (the landmark hull within it).
  const FaceBox frontal_box = fusion.box_for(frontal_pose);
  const cv::Mat region = face_region(*seq, frontal_box.rect);
  const int dropped = static_cast<int>(seq->depth.size()) - run->fused;
  const DepthErrors de = depth_errors(*seq, view, region);
  nlohmann::json j;
  j["seed"] = seed;
  j["uri"] = uri;
  j["frames"] = seq->depth.size();
  j["fused_frames"] = run->fused;
  j["lost_frames"] = run->lost;
  j["dropped_frames"] = dropped;
  j["pose_error_mm_max"] = pe.max_mm;
  j["pose_error_mm_mean"] = pe.mean_mm;
  j["pose_error_deg_max"] = pe.max_deg;
  j["pose_error_deg_mean"] = pe.mean_deg;
  j["camera_centre_error_mm_max"] = pe.camera_max_mm;
  j["camera_centre_error_mm_mean"] = pe.camera_mean_mm;
  j["fused_depth_mae_mm"] = de.fused_mae_mm;
  j["fused_depth_p95_mm"] = de.fused_p95_mm;
  j["fused_depth_max_mm"] = de.fused_max_mm;
  j["raw_depth_mae_mm"] = de.raw_mae_mm;
  j["fused_depth_bias_mm"] = de.fused_bias_mm;
  j["raw_depth_bias_mm"] = de.raw_bias_mm;
  j["raw_depth_p95_mm"] = de.raw_p95_mm;
  j["raw_depth_max_mm"] = de.raw_max_mm;
  j["fill_fraction"] = de.fill;
  j["face_pixels"] = de.face_pixels;
  j["box"] = {frontal_box.rect.x0, frontal_box.rect.y0, frontal_box.rect.width(),
              frontal_box.rect.height()};
  j["face_box"] = box_json(*choice);
  std::cerr << "  box " << j["face_box"].dump() << "\n";
  std::cerr << "  pose max " << pe.max_mm << " mm " << pe.max_deg << " deg; fused "
            << de.fused_mae_mm << " mm vs raw " << de.raw_mae_mm << " mm; fill " << de.fill
            << "; lost " << run->lost << ", dropped " << dropped << " of " << seq->depth.size()
            << " (box: " << choice->source << (choice->note.empty() ? "" : ", " + choice->note)
            << ")\n";
  if (first) {
    const std::filesystem::path png = options.get("png");
    if (!png.empty()) {
      if (auto ok = write_error_map(png, de, frontal_box.rect, scale); !ok) return ok.failure();
      result["error_map_png"] = std::filesystem::absolute(png).string();
      std::cerr << "  error map: " << png.string() << "\n";
    }
    const std::filesystem::path mesh_path = options.get("mesh");
    if (!mesh_path.empty()) {
      const TriangleMesh mesh = fusion.extract_mesh();
      if (auto ok = write_ply(mesh_path, mesh); !ok) return ok.failure();
      result["synthetic_mesh_ply"] = std::filesystem::absolute(mesh_path).string();
      result["synthetic_mesh_triangles"] = mesh.triangles.size();
    }
  }
  return SeedRun{std::move(j), pe, de, run->lost, dropped};
}

// The real dump (`real`: a directory or a .tar.xz): must run to the end without losing track,
// and give a mesh.
Result<nlohmann::json> eval_real_dump(const ParsedOptions& options, const std::string& real,
                                      const FusionOptions& fusion_options, FaceFusion& fusion,
                                      std::optional<LandmarkDetector>& detector) {
  auto scratch = ScratchDirectory::create("facebooth-eval-fusion-");
  if (!scratch) return scratch.failure();
  auto dir = dump_directory(real, scratch->path());
  if (!dir) return dir.failure();
  const std::string uri = "replay:" + dir->string();
  std::cerr << "eval fusion: real dump " << uri << " ...\n";
  auto seq = load_sequence(uri, 1 << 20, 0);
  if (!seq) return seq.failure();
  auto choice = choose_box(options.get("real-box"), *seq, detector);
  if (!choice) return choice.failure();
  FusionOptions real_options = fusion_options;
  auto run = run_fusion(fusion, *seq, choice->box, real_options, options.flag("verbose"));
  if (!run) return run.failure();
  nlohmann::json j;
  j["uri"] = real;
  j["frames"] = seq->depth.size();
  j["fused_frames"] = run->fused;
  j["lost_frames"] = run->lost;
  j["lost_frame_indices"] = run->lost_frames;
  j["dropped_frames"] = static_cast<int>(seq->depth.size()) - run->fused;
  j["box"] = {choice->box.rect.x0, choice->box.rect.y0, choice->box.rect.width(),
              choice->box.rect.height()};
  j["face_box"] = box_json(*choice);
  double max_step_mm = 0, max_step_deg = 0;
  for (std::size_t i = 1; i < run->reports.size(); ++i) {
    const Eigen::Isometry3d d = run->reports[i - 1].world_from_camera.isometry().inverse() *
                                run->reports[i].world_from_camera.isometry();
    max_step_mm = std::max(max_step_mm, d.translation().norm());
    max_step_deg = std::max(max_step_deg, angle_deg(d.rotation()));
  }
  const Eigen::Isometry3d last = run->reports.back().world_from_camera.isometry();
  j["final_camera_translation_mm"] = last.translation().norm();
  j["final_camera_rotation_deg"] = angle_deg(last.rotation());
  j["max_frame_step_mm"] = max_step_mm;
  j["max_frame_step_deg"] = max_step_deg;
  j["ran_to_end"] = run->reports.size() == seq->depth.size();
  const TriangleMesh mesh = fusion.extract_mesh();
  j["mesh_triangles"] = mesh.triangles.size();
  const std::filesystem::path mesh_path = options.get("real-mesh");
  if (!mesh_path.empty()) {
    if (auto ok = write_ply(mesh_path, mesh); !ok) return ok.failure();
    j["mesh_ply"] = std::filesystem::absolute(mesh_path).string();
  }
  std::cerr << "  " << run->fused << "/" << seq->depth.size() << " fused, " << run->lost
            << " lost, mesh " << mesh.triangles.size() << " triangles\n";
  return j;
}

// One eval fusion run; `world` (a world_presets.hpp scenario, or empty) is appended to the
// synthetic URI. With `sink` the JSON goes there (and the real dump is skipped), else to stdout.
int eval_fusion_once(const ParsedOptions& options, const std::string& world, nlohmann::json* sink) {
  auto seeds = options.get_int("seeds");
  if (!seeds) return report_failure(seeds.error());
  auto first_seed = options.get_int("first-seed");
  if (!first_seed) return report_failure(first_seed.error());
  auto frames = options.get_int("frames");
  if (!frames) return report_failure(frames.error());
  auto frontal = options.get_int("frontal-frame");
  if (!frontal) return report_failure(frontal.error());
  auto scale = options.get_double("error-scale-mm");
  if (!scale) return report_failure(scale.error());
  if (*seeds < 1 || *frames < 2 || *frontal < 0 || *frontal >= *frames || *scale <= 0)
    return report_failure(
        {"--seeds >= 1, --frames >= 2, 0 <= --frontal-frame < --frames and "
         "--error-scale-mm > 0 are required"});
  auto fusion_options = parse_fusion_options(options);
  if (!fusion_options) return report_failure(fusion_options.error());

  nlohmann::json result;
  nlohmann::json per_seed = nlohmann::json::array();
  PoseErrors worst;
  double fused_sum = 0, raw_sum = 0, fill_min = 1.0, fill_sum = 0, fused_max_seed = 0;
  int total_lost = 0, total_dropped = 0;
  FaceFusion fusion;
  std::optional<LandmarkDetector> detector;
  for (long long s = 0; s < *seeds; ++s) {
    const int seed = static_cast<int>(*first_seed + s);
    auto seed_run = eval_seed(options, world, seed, *frames, static_cast<int>(*frontal), *scale,
                              *fusion_options, fusion, detector, s == 0, result);
    if (!seed_run) return report_failure(seed_run.error());
    const PoseErrors& pe = seed_run->pose;
    const DepthErrors& de = seed_run->depth;
    const int dropped = seed_run->dropped;
    per_seed.push_back(std::move(seed_run->json));
    worst.max_mm = std::max(worst.max_mm, pe.max_mm);
    worst.max_deg = std::max(worst.max_deg, pe.max_deg);
    worst.camera_max_mm = std::max(worst.camera_max_mm, pe.camera_max_mm);
    worst.mean_mm += pe.mean_mm / *seeds;
    worst.mean_deg += pe.mean_deg / *seeds;
    worst.camera_mean_mm += pe.camera_mean_mm / *seeds;
    fused_sum += de.fused_mae_mm;
    fused_max_seed = std::max(fused_max_seed, de.fused_mae_mm);
    raw_sum += de.raw_mae_mm;
    fill_min = std::min(fill_min, de.fill);
    fill_sum += de.fill;
    total_lost += seed_run->lost;
    total_dropped += dropped;
  }
  result["seeds"] = *seeds;
  result["frames_per_seed"] = *frames;
  result["pose_error_definition"] =
      "the head's pose relative to the first frame: E = (M0 Mk^-1)^-1 (G0^-1 Gk); deg = angle "
      "of E; mm = displacement E causes at the face (the centroid of the 68 ground-truth "
      "landmarks of frame k), where the head is; camera_centre_error_mm = |translation of E|, "
      "the same error seen at the camera centre ~0.7 m away, dominated by the rotation error "
      "times that lever arm (0.1 deg is 1.2 mm there)";
  result["pose_error_mm_max"] = worst.max_mm;
  result["pose_error_deg_max"] = worst.max_deg;
  result["pose_error_mm_mean"] = worst.mean_mm;
  result["pose_error_deg_mean"] = worst.mean_deg;
  result["camera_centre_error_mm_max"] = worst.camera_max_mm;
  result["camera_centre_error_mm_mean"] = worst.camera_mean_mm;
  result["fused_depth_mae_mm"] = fused_sum / *seeds;
  result["fused_depth_mae_mm_worst_seed"] = fused_max_seed;
  result["raw_depth_mae_mm"] = raw_sum / *seeds;
  result["fill_fraction"] = fill_sum / *seeds;
  result["fill_fraction_min"] = fill_min;
  result["lost_frames"] = total_lost;
  // Frames fusion could not follow (lost, or before it started): not fused, counted; the take
  // keeps the frames it fused.
  result["dropped_frames"] = total_dropped;
  result["per_seed"] = per_seed;

  // The real dump: must run to the end without losing track, and give a mesh.
  if (const std::string real = sink ? "off" : options.get("real"); real != "off") {
    auto j = eval_real_dump(options, real, *fusion_options, fusion, detector);
    if (!j) return report_failure(j.error());
    result["real_dump"] = std::move(*j);
  }
  nlohmann::json targets;
  targets["pose_error_mm_max"] = 1.0;
  targets["pose_error_deg_max"] = 0.5;
  targets["fused_depth_mae_mm"] = 0.5;
  result["targets"] = targets;
  result["meets_targets"] =
      worst.max_mm <= 1.0 && worst.max_deg <= 0.5 && fused_sum / *seeds <= 0.5;
  if (sink) {
    *sink = std::move(result);
    return kExitOk;
  }
  std::cout << result.dump(2) << std::endl;
  return kExitOk;
}

}  // namespace

int run_eval_fusion(const ParsedOptions& options) {
  const std::string scenario = options.get("scenario");
  if (scenario.empty()) return eval_fusion_once(options, "", nullptr);
  // A plain baseline and every part alone for realistic, then the scenario (the top level);
  // the real dump is not part of a scenario run.
  auto parts = scenario_parts(scenario);
  if (!parts) return report_failure(parts.error());
  nlohmann::json scenarios, out;
  for (const auto& part : *parts) {
    nlohmann::json j;
    if (int rc = eval_fusion_once(options, part == "baseline" ? "none" : part, &j); rc != kExitOk)
      return rc;
    j.erase("per_seed");
    if (part == scenario) out = j;
    scenarios[part] = std::move(j);
  }
  out["scenario"] = scenario;
  out["scenarios"] = scenarios;
  std::cout << out.dump(2) << std::endl;
  return kExitOk;
}

}  // namespace fb::cli::fusion_lab
