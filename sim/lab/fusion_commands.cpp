// facebooth-lab eval fusion | bench fusion: the face-box KinectFusion (algo/fusion) scored against
// the synthetic camera's ground truth, run on the real dump, and timed against Open3D on the same
// frames. One JSON object on stdout, progress on stderr.
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <numeric>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "sim/camera/frame_truth.hpp"
#include "algo/fusion/face_fusion.hpp"
#include "algo/landmarks/face_region_box.hpp"
#include "sim/camera/world_presets.hpp"
#include "sim/lab/lab_commands.hpp"
#include "host/cli/frame_open.hpp"
#include "host/cli/scratch_directory.hpp"
#include "host/cli/stats.hpp"
#include "sim/scoring/take_runner.hpp"

namespace fb::cli {
namespace {

#ifndef FB_REAL_DUMP_DEFAULT
#define FB_REAL_DUMP_DEFAULT "../shared/kinect/openiss-desk/test-recording-first90.tar.xz"
#endif

// ---------------------------------------------------------------------------------------------
// Frames held in memory, so that camera rendering or decoding is never part of a timing.

struct Sequence {
  std::string uri;
  PinholeIntrinsics intrinsics;
  std::vector<DepthImage> depth;
  ColorImage first_color;                    // frame 0's, where the face box is detected
  KinectCalibration calibration;             // the registration the camera reports
  std::vector<RigidPose> camera_from_model;  // truth, empty for real recordings
  std::vector<std::vector<Eigen::Vector3d>> landmarks_3d;
  // Truth of the frontal frame only (the one the fused depth is scored on).
  int frontal = 0;
  Image<float> frontal_noiseless;
  std::vector<Eigen::Vector2d> frontal_landmarks_px;
};

Result<Sequence> load_sequence(const std::string& uri, long long max_frames, int frontal) {
  auto camera = open_started_camera(uri);
  if (!camera) return camera.failure();
  Sequence seq;
  seq.uri = uri;
  seq.intrinsics = (*camera)->info().depth_intrinsics;
  seq.calibration = (*camera)->info().calibration;
  seq.frontal = frontal;
  RgbdFrame frame;
  int timeouts = 0;
  while (static_cast<long long>(seq.depth.size()) < max_frames) {
    auto status = (*camera)->next_frame(frame, std::chrono::milliseconds(2000));
    if (!status) return status.failure();
    if (*status == FrameStatus::kEndOfStream) break;
    if (*status == FrameStatus::kTimeout) {
      if (++timeouts > 5) return fail("camera '" + uri + "' stopped delivering frames");
      continue;
    }
    const int index = static_cast<int>(seq.depth.size());
    if (index == 0) seq.first_color = frame.color;
    seq.depth.push_back(frame.depth_mm);
    if (const FrameTruth* truth = frame_truth(**camera)) {
      seq.camera_from_model.push_back(truth->camera_from_model);
      seq.landmarks_3d.push_back(truth->landmarks_3d);
      if (index == frontal) {
        seq.frontal_noiseless = truth->noiseless_depth_mm;
        seq.frontal_landmarks_px = truth->landmarks_depth_px;
      }
    }
  }
  (*camera)->stop();
  if (seq.depth.empty()) return fail("camera '" + uri + "' delivered no frames");
  if (seq.intrinsics.fx <= 0.0) return fail("camera '" + uri + "' reports no depth intrinsics");
  return seq;
}

// ---------------------------------------------------------------------------------------------
// Options shared by both commands.

std::vector<OptionSpec> fusion_option_specs() {
  return {
      {"box", "detect|kiosk|X,Y,W,H",
       "face box in the depth image: detect = dlib on frame 0's colour image through the "
       "registration, grown to the forehead and chin (the kiosk rectangle when no face is "
       "found); kiosk = the fixed 200x240 rectangle in the middle of 640x480",
       "detect"},
      {"box-follows", "on|off", "the face box follows the fused pose over the take", "on"},
      {"volume-mm", "MM", "TSDF cube side", "300"},
      {"resolution", "N", "voxels per side (multiple of 8)", "256"},
      {"truncation-mm", "MM", "TSDF truncation", "8"},
      {"max-weight", "N", "running-average weight cap (1-31)", "31"},
      {"max-angle-deg", "DEG", "integrate pixels seen at most this far from head-on (90: all)",
       "90"},
      {"icp-iterations", "C,M,F",
       "ICP iteration caps on the coarse, middle and full-resolution levels (each level stops "
       "earlier when converged)",
       "4,3,3"},
      {"icp-level0-step", "N", "full-resolution ICP points: 1 = every pixel, 2 = a checkerboard",
       "2"},
      {"model-view-level", "L",
       "pyramid level the tracker's model view is ray-cast at (0 = full resolution)", "1"},
      {"integrate-lanes", "N",
       "vector width of the voxel update: 0 = the widest this CPU runs (8 with AVX2), 4 = the "
       "width of the device's NEON",
       "0"},
  };
}

Result<FaceBox> parse_box(const std::string& text, const PinholeIntrinsics& k) {
  if (text.empty() || text == "kiosk") return default_face_box(k.width, k.height);
  FaceBox box;
  char c1 = 0, c2 = 0, c3 = 0;
  std::istringstream in(text);
  if (!(in >> box.x >> c1 >> box.y >> c2 >> box.width >> c3 >> box.height) || c1 != ',' ||
      c2 != ',' || c3 != ',' || box.width <= 0 || box.height <= 0)
    return fail("--box must be X,Y,W,H in depth-image pixels, e.g. 220,120,200,240 (got '" + text +
                "')");
  return box;
}

// The face box a sequence is fused in, and where it came from.
struct BoxChoice {
  FaceBox box;
  std::string source;  // "dlib", "kiosk" or "given"
  std::string note;    // why detection gave way to the kiosk rectangle
};

// `text`: detect (or empty), kiosk, or X,Y,W,H. Detection loads dlib's model once into
// `detector`; without it, or without a face, the kiosk rectangle (the note says why).
Result<BoxChoice> choose_box(const std::string& text, const Sequence& seq,
                             std::optional<LandmarkDetector>& detector) {
  BoxChoice c;
  if (!text.empty() && text != "detect") {
    auto box = parse_box(text, seq.intrinsics);
    if (!box) return box.failure();
    c.box = *box;
    c.source = text == "kiosk" ? "kiosk" : "given";
    return c;
  }
  c.box = default_face_box(seq.intrinsics.width, seq.intrinsics.height);
  c.source = "kiosk";
  if (!detector) {
    auto loaded = load_landmark_detector("");
    if (!loaded) {
      c.note = loaded.error().message;
      return c;
    }
    detector.emplace(std::move(*loaded));
  }
  auto region = detect_face_region(*detector, seq.first_color, seq.depth.front(),
                                   KinectRegistration(seq.calibration), FaceProportions{});
  if (!region) {
    c.note = region.error().message;
    return c;
  }
  c.box = region->box;
  c.source = "dlib";
  return c;
}

nlohmann::json box_json(const BoxChoice& c) {
  nlohmann::json j = {{"source", c.source},
                      {"x", c.box.x},
                      {"y", c.box.y},
                      {"width", c.box.width},
                      {"height", c.box.height}};
  if (c.box.face_depth_mm > 0.0f) j["face_depth_mm"] = c.box.face_depth_mm;
  if (!c.note.empty()) j["note"] = c.note;
  return j;
}

Result<FusionOptions> parse_fusion_options(const ParsedOptions& options) {
  FusionOptions o;
  const std::string follows = options.get("box-follows");
  if (follows != "on" && follows != "off") return fail("--box-follows must be on or off");
  o.box_follows_face = follows == "on";

  auto volume = options.get_double("volume-mm");
  if (!volume) return volume.failure();
  auto resolution = options.get_int("resolution");
  if (!resolution) return resolution.failure();
  auto truncation = options.get_double("truncation-mm");
  if (!truncation) return truncation.failure();
  auto weight = options.get_int("max-weight");
  if (!weight) return weight.failure();
  auto angle = options.get_double("max-angle-deg");
  if (!angle) return angle.failure();
  o.integrate_max_angle_deg = static_cast<float>(*angle);
  o.volume_size_mm = static_cast<float>(*volume);
  o.volume_resolution = static_cast<int>(*resolution);
  o.truncation_mm = static_cast<float>(*truncation);
  o.max_weight = static_cast<int>(*weight);
  {
    const std::string text = options.get("icp-iterations");
    char c1 = 0, c2 = 0;
    int coarse = 0, middle = 0, fine = 0;
    std::istringstream in(text);
    if (!(in >> coarse >> c1 >> middle >> c2 >> fine) || c1 != ',' || c2 != ',' || coarse < 0 ||
        middle < 0 || fine < 1 || coarse + middle + fine > 100)
      return fail(
          "--icp-iterations must be C,M,F (coarse, middle, full resolution; F >= 1), "
          "e.g. 8,5,4 (got '" +
          text + "')");
    o.icp_iterations = {fine, middle, coarse};
  }
  auto step = options.get_int("icp-level0-step");
  if (!step) return step.failure();
  auto view_level = options.get_int("model-view-level");
  if (!view_level) return view_level.failure();
  if (*step < 1 || *step > 2) return fail("--icp-level0-step must be 1 or 2");
  if (*view_level < 0 || *view_level > 2) return fail("--model-view-level must be 0, 1 or 2");
  auto lanes = options.get_int("integrate-lanes");
  if (!lanes) return lanes.failure();
  if (!TsdfIntegrator::lanes_supported(static_cast<int>(*lanes)))
    return fail(
        "--integrate-lanes must be 0, 4, or 8 where the CPU has AVX2 (this one runs at "
        "most " +
        std::to_string(TsdfIntegrator::widest_lanes()) + ")");
  o.integrate_lanes = static_cast<int>(*lanes);
  o.icp_level0_step = static_cast<int>(*step);
  o.model_view_level = static_cast<int>(*view_level);
  return o;
}

// ---------------------------------------------------------------------------------------------
// Running the pipeline over a sequence.

struct Run {
  std::vector<FrameReport> reports;
  int fused = 0;
  int lost = 0;
  std::vector<int> lost_frames;
};

Result<Run> run_fusion(FaceFusion& fusion, const Sequence& seq, const FaceBox& box,
                       const FusionOptions& options, bool verbose = false,
                       bool truth_poses = false) {
  if (auto ok = fusion.reset(seq.intrinsics, box, options); !ok) return ok.failure();
  Run run;
  run.reports.reserve(seq.depth.size());
  for (std::size_t i = 0; i < seq.depth.size(); ++i) {
    RigidPose known;
    if (truth_poses && i < seq.camera_from_model.size()) {
      // camera_0_from_camera_i = M_0 M_i^-1
      const Eigen::Isometry3d g =
          seq.camera_from_model[0].isometry() * seq.camera_from_model[i].isometry().inverse();
      known.rotation = Eigen::Quaterniond(g.rotation());
      known.translation = g.translation();
    }
    const FrameReport r = fusion.process(
        seq.depth[i], truth_poses && i < seq.camera_from_model.size() ? &known : nullptr);
    run.fused += r.fused;
    if (r.state == TrackingState::kLost) {
      ++run.lost;
      run.lost_frames.push_back(static_cast<int>(i));
    }
    if (verbose)
      std::fprintf(stderr,
                   "  frame %zu: %s%s%s valid %d inliers %d rms %.2f mm it %d | cpu ms pre %.2f "
                   "icp %.2f int %.2f ray %.2f, %d bricks\n",
                   i, to_string(r.state), *r.loss_reason ? " - " : "", r.loss_reason,
                   r.valid_pixels, r.inliers, r.rms_mm, r.iterations, r.cpu_times.preprocess_ms,
                   r.cpu_times.track_ms, r.cpu_times.integrate_ms, r.cpu_times.raycast_ms,
                   r.integrated_bricks);
    run.reports.push_back(r);
  }
  return run;
}

double angle_deg(const Eigen::Matrix3d& r) {
  return std::acos(std::clamp((r.trace() - 1.0) * 0.5, -1.0, 1.0)) * 180.0 / M_PI;
}

// Pose error of frame k relative to the first fused frame f0: truth relative motion
// camera_f0_from_camera_k = M_f0 M_k^-1 against the tracked G_f0^-1 G_k; E = truth^-1 tracked.
// The pose is the head's: its angle is that of E, its translation error is the displacement E
// causes at the face (the centroid of the 68 landmarks of frame k), where the head is. The
// translation of E itself (the camera centre, ~0.7 m from the face) is reported beside it; it
// is dominated by the rotation error times that lever arm (0.1 deg there is 1.2 mm), so it
// would count the rotation error twice.
struct PoseErrors {
  double max_mm = 0, mean_mm = 0, max_deg = 0, mean_deg = 0, camera_max_mm = 0, camera_mean_mm = 0;
  int frames = 0;
};

PoseErrors pose_errors(const Sequence& seq, const Run& run, bool verbose = false) {
  PoseErrors e;
  int f0 = -1;
  for (std::size_t i = 0; i < run.reports.size(); ++i)
    if (run.reports[i].state == TrackingState::kStarted) {
      f0 = static_cast<int>(i);
      break;
    }
  if (f0 < 0 || seq.camera_from_model.size() != run.reports.size()) return e;
  const Eigen::Isometry3d g0_inv = run.reports[f0].world_from_camera.isometry().inverse();
  const Eigen::Isometry3d m0 = seq.camera_from_model[f0].isometry();
  for (std::size_t k = f0; k < run.reports.size(); ++k) {
    if (!run.reports[k].fused) continue;
    const Eigen::Isometry3d truth = m0 * seq.camera_from_model[k].isometry().inverse();
    const Eigen::Isometry3d tracked = g0_inv * run.reports[k].world_from_camera.isometry();
    const Eigen::Isometry3d err = truth.inverse() * tracked;
    Eigen::Vector3d face = Eigen::Vector3d::Zero();
    if (k < seq.landmarks_3d.size() && !seq.landmarks_3d[k].empty()) {
      for (const auto& p : seq.landmarks_3d[k]) face += p;
      face /= static_cast<double>(seq.landmarks_3d[k].size());
    }
    const double camera_mm = err.translation().norm();
    const double deg = angle_deg(err.rotation());
    const double face_mm = (err * face - face).norm();
    if (verbose) {
      const Eigen::AngleAxisd aa(err.rotation());
      const Eigen::AngleAxisd truth_aa(truth.rotation());
      const Eigen::Vector3d face_err = err * face - face;
      std::fprintf(stderr,
                   "  frame %zu: error %.3f mm %.3f deg (axis %.2f %.2f %.2f), face %.3f mm "
                   "(%.3f %.3f %.3f); truth motion %.2f deg\n",
                   k, camera_mm, deg, aa.axis().x(), aa.axis().y(), aa.axis().z(), face_mm,
                   face_err.x(), face_err.y(), face_err.z(), truth_aa.angle() * 180.0 / M_PI);
    }
    e.max_mm = std::max(e.max_mm, face_mm);
    e.max_deg = std::max(e.max_deg, deg);
    e.camera_max_mm = std::max(e.camera_max_mm, camera_mm);
    e.mean_mm += face_mm;
    e.mean_deg += deg;
    e.camera_mean_mm += camera_mm;
    ++e.frames;
  }
  if (e.frames > 0) {
    e.mean_mm /= e.frames;
    e.mean_deg /= e.frames;
    e.camera_mean_mm /= e.frames;
  }
  return e;
}

// Face region of the frontal frame: inside the convex hull of the 68 landmarks (brows to chin),
// where the noiseless rendering has surface, inside the face box.
cv::Mat face_region(const Sequence& seq, const FaceBox& box) {
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
                             const FaceBox& box, double scale_mm) {
  const int pad = 10;
  auto panel = [&](const cv::Mat& err, const std::string& title, double mae) {
    cv::Mat roi = err(cv::Rect(box.x, box.y, box.width, box.height));
    cv::Mat out(box.height, box.width, CV_8UC3, cv::Scalar(0, 0, 0));
    cv::Mat abs8(box.height, box.width, CV_8U, cv::Scalar(0));
    cv::Mat has(box.height, box.width, CV_8U, cv::Scalar(0));
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
  try {
    if (!cv::imwrite(path.string(), row)) return fail("could not write " + path.string());
  } catch (const cv::Exception& ex) {
    return fail("could not write " + path.string() + ": " + ex.what());
  }
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

// ---------------------------------------------------------------------------------------------
// facebooth-lab eval fusion

std::string synthetic_uri(const std::string& base, int seed, long long frames) {
  std::string uri = base.empty() ? "synthetic:motion=headturn" : base;
  uri += (uri.find(':') == uri.size() - 1 ? "" : ",");
  return uri + "seed=" + std::to_string(seed) + ",frames=" + std::to_string(frames);
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
    std::string base = options.get("synthetic");
    if (!world.empty()) base += (base.ends_with(":") ? "" : ",") + ("world=" + world);
    const std::string uri = synthetic_uri(base, seed, *frames);
    std::cerr << "eval fusion: " << uri << " ...\n";
    auto seq = load_sequence(uri, *frames, static_cast<int>(*frontal));
    if (!seq) return report_failure(seq.error());
    if (seq->camera_from_model.empty() || seq->frontal_noiseless.empty())
      return report_failure({"camera '" + uri + "' has no ground truth; use a synthetic URI"});
    auto choice = choose_box(options.get("box"), *seq, detector);
    if (!choice) return report_failure(choice.error());
    auto run = run_fusion(fusion, *seq, choice->box, *fusion_options, options.flag("verbose"),
                          options.flag("truth-poses"));
    if (!run) return report_failure(run.error());
    const PoseErrors pe = pose_errors(*seq, *run, options.flag("verbose"));
    const RigidPose frontal_pose = run->reports[seq->frontal].world_from_camera;
    const SurfaceView view = fusion.render(frontal_pose);
    // Scored inside the box the frontal frame was fused in (the landmark hull within it).
    const FaceBox frontal_box = fusion.box_for(frontal_pose);
    const cv::Mat region = face_region(*seq, frontal_box);
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
    j["box"] = {frontal_box.x, frontal_box.y, frontal_box.width, frontal_box.height};
    j["face_box"] = box_json(*choice);
    per_seed.push_back(j);
    std::cerr << "  pose max " << pe.max_mm << " mm " << pe.max_deg << " deg; fused "
              << de.fused_mae_mm << " mm vs raw " << de.raw_mae_mm << " mm; fill " << de.fill
              << "; lost " << run->lost << ", dropped " << dropped << " of " << seq->depth.size()
              << " (box: " << choice->source << (choice->note.empty() ? "" : ", " + choice->note)
              << ")\n";
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
    total_lost += run->lost;
    total_dropped += dropped;
    if (s == 0) {
      const std::filesystem::path png = options.get("png");
      if (!png.empty()) {
        if (auto ok = write_error_map(png, de, frontal_box, *scale); !ok)
          return report_failure(ok.error());
        result["error_map_png"] = std::filesystem::absolute(png).string();
        std::cerr << "  error map: " << png.string() << "\n";
      }
      const std::filesystem::path mesh_path = options.get("mesh");
      if (!mesh_path.empty()) {
        const TriangleMesh mesh = fusion.extract_mesh();
        if (auto ok = write_ply(mesh_path, mesh); !ok) return report_failure(ok.error());
        result["synthetic_mesh_ply"] = std::filesystem::absolute(mesh_path).string();
        result["synthetic_mesh_triangles"] = mesh.triangles.size();
      }
    }
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
  const std::string real = sink ? "off" : options.get("real");
  if (real != "off") {
    auto scratch = ScratchDirectory::create("facebooth-eval-fusion-");
    if (!scratch) return report_failure(scratch.error());
    auto dir = dump_directory(real, scratch->path());
    if (!dir) return report_failure(dir.error());
    const std::string uri = "replay:" + dir->string();
    std::cerr << "eval fusion: real dump " << uri << " ...\n";
    auto seq = load_sequence(uri, 1 << 20, 0);
    if (!seq) return report_failure(seq.error());
    auto choice = choose_box(options.get("real-box"), *seq, detector);
    if (!choice) return report_failure(choice.error());
    FusionOptions real_options = *fusion_options;
    auto run = run_fusion(fusion, *seq, choice->box, real_options, options.flag("verbose"));
    if (!run) return report_failure(run.error());
    nlohmann::json j;
    j["uri"] = real;
    j["frames"] = seq->depth.size();
    j["fused_frames"] = run->fused;
    j["lost_frames"] = run->lost;
    j["lost_frame_indices"] = run->lost_frames;
    j["dropped_frames"] = static_cast<int>(seq->depth.size()) - run->fused;
    j["box"] = {choice->box.x, choice->box.y, choice->box.width, choice->box.height};
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
      if (auto ok = write_ply(mesh_path, mesh); !ok) return report_failure(ok.error());
      j["mesh_ply"] = std::filesystem::absolute(mesh_path).string();
    }
    std::cerr << "  " << run->fused << "/" << seq->depth.size() << " fused, " << run->lost
              << " lost, mesh " << mesh.triangles.size() << " triangles\n";
    result["real_dump"] = j;
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

int run_eval_fusion(const ParsedOptions& options) {
  const std::string scenario = options.get("scenario");
  if (scenario.empty()) return eval_fusion_once(options, "", nullptr);
  SyntheticOptions probe;
  if (auto ok = apply_world_preset(scenario, 1, probe); !ok) return report_failure(ok.error());
  // A plain baseline and every part alone for realistic, then the scenario (the top level);
  // the real dump is not part of a scenario run.
  std::vector<std::string> parts;
  if (scenario == "realistic") {
    parts.push_back("baseline");
    for (const auto& p : world_parts()) parts.push_back(p);
  }
  parts.push_back(scenario);
  nlohmann::json scenarios, out;
  for (const auto& part : parts) {
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

// ---------------------------------------------------------------------------------------------
// facebooth-lab bench fusion

struct Timing {
  StageTimes cpu;   // mean per timed frame, calling thread's CPU time
  StageTimes wall;  // mean per timed frame
  int timed = 0;
};

// Frames 0 and 1 are left out (volume placement, first model, cold caches).
Timing time_run(const Run& run) {
  Timing t;
  for (std::size_t i = 2; i < run.reports.size(); ++i) {
    const FrameReport& r = run.reports[i];
    if (!r.fused) continue;
    t.cpu.preprocess_ms += r.cpu_times.preprocess_ms;
    t.cpu.track_ms += r.cpu_times.track_ms;
    t.cpu.integrate_ms += r.cpu_times.integrate_ms;
    t.cpu.raycast_ms += r.cpu_times.raycast_ms;
    t.wall.preprocess_ms += r.times.preprocess_ms;
    t.wall.track_ms += r.times.track_ms;
    t.wall.integrate_ms += r.times.integrate_ms;
    t.wall.raycast_ms += r.times.raycast_ms;
    ++t.timed;
  }
  const double n = std::max(1, t.timed);
  for (StageTimes* s : {&t.cpu, &t.wall}) {
    s->preprocess_ms /= n;
    s->track_ms /= n;
    s->integrate_ms /= n;
    s->raycast_ms /= n;
  }
  return t;
}

nlohmann::json stage_json(const StageTimes& s) {
  return {{"preprocess_ms", s.preprocess_ms},
          {"icp_ms", s.track_ms},
          {"integrate_ms", s.integrate_ms},
          {"raycast_ms", s.raycast_ms},
          {"icp_integrate_raycast_ms", s.track_ms + s.integrate_ms + s.raycast_ms},
          {"total_ms", s.total_ms()}};
}

std::filesystem::path self_directory() {
  std::error_code ec;
  const auto exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  return ec ? std::filesystem::path() : exe.parent_path();
}

std::string open3d_bench_path(const std::string& option) {
  if (!option.empty()) return option;
  const auto self = self_directory();
  for (const auto& candidate :
       {self / "facebooth-bench-open3d",
        self / ".." / ".." / "bench" / "fusion_open3d" / "facebooth-bench-open3d"})
    if (std::filesystem::exists(candidate)) return candidate.string();
#ifdef FB_OPEN3D_BENCH_PATH
  if (std::filesystem::exists(FB_OPEN3D_BENCH_PATH)) return FB_OPEN3D_BENCH_PATH;
#endif
  return {};
}

// Runs a command with OMP_NUM_THREADS=1 and returns its stdout.
Result<std::string> capture_output(const std::string& command) {
  const std::string full = "OMP_NUM_THREADS=1 " + command;
  FILE* pipe = popen(full.c_str(), "r");
  if (!pipe) return fail("could not run " + command);
  std::string out;
  char buffer[65536];
  std::size_t n;
  while ((n = fread(buffer, 1, sizeof buffer, pipe)) > 0) out.append(buffer, n);
  const int status = pclose(pipe);
  if (status != 0)
    return fail("'" + command + "' failed (exit status " + std::to_string(WEXITSTATUS(status)) +
                ")");
  return out;
}

Result<void> write_frames_file(const std::filesystem::path& path, const Sequence& seq,
                               const FaceBox& box, const FaceFusion& fusion) {
  std::ofstream out(path, std::ios::binary);
  if (!out) return fail("cannot write " + path.string());
  const PinholeIntrinsics& k = seq.intrinsics;
  const FusionOptions& o = fusion.options();
  // Depth gate as ours, with the far bound at the back of our volume (the wall behind the head
  // is outside the volume for us, so it must not be integrated by Open3D either).
  const double far = fusion.volume().origin().z() + fusion.volume().size_mm();
  out << "FBDEPTH1 " << k.width << ' ' << k.height << ' ' << seq.depth.size() << ' ' << k.fx << ' '
      << k.fy << ' ' << k.cx << ' ' << k.cy << ' ' << box.x << ' ' << box.y << ' ' << box.width
      << ' ' << box.height << ' ' << o.min_depth_mm << ' ' << std::min<double>(far, o.max_depth_mm)
      << ' ' << fusion.volume().voxel_size() << ' ' << o.truncation_mm << '\n';
  for (const auto& d : seq.depth)
    out.write(reinterpret_cast<const char*>(d.pixels.data()),
              static_cast<std::streamsize>(d.pixels.size() * 2));
  if (!out) return fail("write error on " + path.string());
  return success();
}

// The fastest of `repeats` runs: ICP + integrate + ray-cast per frame, as CPU time of the
// calling thread for one thread and as wall time for more (CPU time of one thread says nothing
// about a split).
struct FastestRun {
  Timing timing;
  double ms_per_frame = 0.0;
};

Result<FastestRun> fastest_run(FaceFusion& fusion, const Sequence& seq, const FaceBox& box,
                               const FusionOptions& options, long long repeats,
                               const std::string& label) {
  FastestRun best;
  best.ms_per_frame = 1e30;
  for (long long r = 0; r < repeats; ++r) {
    std::cerr << "bench fusion: " << label << ", run " << r + 1 << "/" << repeats << " ...\n";
    auto run = run_fusion(fusion, seq, box, options);
    if (!run) return run.failure();
    const Timing t = time_run(*run);
    const StageTimes& s = options.threads == 1 ? t.cpu : t.wall;
    const double total = s.track_ms + s.integrate_ms + s.raycast_ms;
    if (total < best.ms_per_frame) best = {t, total};
  }
  return best;
}

int run_bench_fusion(const ParsedOptions& options) {
  auto frames = options.get_int("frames");
  if (!frames) return report_failure(frames.error());
  auto seed = options.get_int("seed");
  if (!seed) return report_failure(seed.error());
  auto repeats = options.get_int("repeats");
  if (!repeats) return report_failure(repeats.error());
  if (*frames < 4 || *repeats < 1)
    return report_failure({"--frames must be at least 4 and --repeats at least 1"});
  auto fusion_options = parse_fusion_options(options);
  if (!fusion_options) return report_failure(fusion_options.error());
  const std::string camera = options.get("camera");
  const std::string uri =
      camera.empty() ? synthetic_uri("", static_cast<int>(*seed), *frames) : camera;
  std::cerr << "bench fusion: loading " << uri << " ...\n";
  auto seq = load_sequence(uri, *frames, 0);
  if (!seq) return report_failure(seq.error());
  std::optional<LandmarkDetector> detector;
  auto choice = choose_box(options.get("box"), *seq, detector);
  if (!choice) return report_failure(choice.error());
  const FaceBox* box = &choice->box;

  nlohmann::json result;
  result["source"] = uri;
  result["frames"] = seq->depth.size();
  result["box"] = {box->x, box->y, box->width, box->height};
  result["face_box"] = box_json(*choice);
  result["volume_mm"] = fusion_options->volume_size_mm;
  result["resolution"] = fusion_options->volume_resolution;
  result["truncation_mm"] = fusion_options->truncation_mm;

  // One thread: the device figure. Best of `repeats` runs (the host is shared; the minimum is
  // the least disturbed one).
  FaceFusion fusion;
  Timing best1;
  double best1_total = 1e30;
  Run last_run;
  std::vector<double> run_totals;
  for (long long r = 0; r < *repeats; ++r) {
    FusionOptions o = *fusion_options;
    o.threads = 1;
    std::cerr << "bench fusion: 1 thread, run " << r + 1 << "/" << *repeats << " ...\n";
    auto run = run_fusion(fusion, *seq, *box, o);
    if (!run) return report_failure(run.error());
    const Timing t = time_run(*run);
    run_totals.push_back(t.cpu.track_ms + t.cpu.integrate_ms + t.cpu.raycast_ms);
    if (t.cpu.track_ms + t.cpu.integrate_ms + t.cpu.raycast_ms < best1_total) {
      best1_total = t.cpu.track_ms + t.cpu.integrate_ms + t.cpu.raycast_ms;
      best1 = t;
    }
    last_run = std::move(*run);
  }
  const PoseErrors pe = pose_errors(*seq, last_run);
  result["ms_per_frame"] = best1.cpu.track_ms + best1.cpu.integrate_ms + best1.cpu.raycast_ms;
  result["ms_per_frame_definition"] =
      "ICP + integrate + ray-cast, one thread, CPU time of that thread, mean over frames 2..N, "
      "best of --repeats runs; preprocessing (bilateral, pyramid, maps) listed separately";
  result["ms_per_frame_runs"] = run_totals;
  {
    std::vector<double> sorted = run_totals;
    std::sort(sorted.begin(), sorted.end());
    const std::size_t n = sorted.size();
    result["ms_per_frame_median"] =
        n % 2 ? sorted[n / 2] : 0.5 * (sorted[n / 2 - 1] + sorted[n / 2]);
  }
  // The host is shared: its load when the runs were timed, to read the absolute figures by.
  if (std::ifstream loadavg("/proc/loadavg"); loadavg) {
    double one = 0.0;
    if (loadavg >> one) result["load_average_1min"] = one;
  }
  result["ms_per_frame_with_preprocess"] = best1.cpu.total_ms();
  result["stages_1thread_cpu"] = stage_json(best1.cpu);
  result["stages_1thread_wall"] = stage_json(best1.wall);
  result["timed_frames"] = best1.timed;
  result["integrate_lanes"] = fusion_options->integrate_lanes ? fusion_options->integrate_lanes
                                                              : TsdfIntegrator::widest_lanes();
  // The device's NEON is 4 lanes wide: when this CPU ran 8, time the 4-lane voxel update too.
  if (result["integrate_lanes"].get<int>() == 8) {
    FusionOptions o = *fusion_options;
    o.threads = 1;
    o.integrate_lanes = 4;
    auto best4 = fastest_run(fusion, *seq, *box, o, *repeats, "1 thread, 4-lane voxel update");
    if (!best4) return report_failure(best4.error());
    result["ms_per_frame_4lanes"] = best4->ms_per_frame;
    result["stages_1thread_cpu_4lanes"] = stage_json(best4->timing.cpu);
  }
  result["lost_frames"] = last_run.lost;
  if (pe.frames > 0) {
    result["pose_error_mm_max"] = pe.max_mm;
    result["pose_error_deg_max"] = pe.max_deg;
  }
  result["tsdf_memory_mb"] = static_cast<double>(fusion.volume().memory_bytes()) / (1 << 20);

  // Two threads: wall time (CPU time of one thread says nothing about a split).
  {
    FusionOptions o = *fusion_options;
    o.threads = 2;
    auto best2 = fastest_run(fusion, *seq, *box, o, *repeats, "2 threads");
    if (!best2) return report_failure(best2.error());
    result["ms_per_frame_2threads"] = best2->ms_per_frame;
    result["stages_2threads_wall"] = stage_json(best2->timing.wall);
  }

  // Open3D on the same frames, box, voxel size and truncation.
  const std::string peer = open3d_bench_path(options.get("open3d"));
  if (options.get("open3d") == "off") {
    result["open3d"] = "skipped (--open3d off)";
  } else if (peer.empty()) {
    result["open3d"] = "not built (install libopen3d-dev and rebuild facebooth-bench-open3d)";
  } else {
    auto scratch = ScratchDirectory::create("facebooth-bench-fusion-");
    if (!scratch) return report_failure(scratch.error());
    // Re-run once so that the volume placement written out is the one of a full run.
    FusionOptions o = *fusion_options;
    o.threads = 1;
    auto run = run_fusion(fusion, *seq, *box, o);
    if (!run) return report_failure(run.error());
    const auto frames_file = scratch->path() / "frames.fbdepth";
    if (auto ok = write_frames_file(frames_file, *seq, *box, fusion); !ok)
      return report_failure(ok.error());
    std::cerr << "bench fusion: Open3D (" << peer << ", 1 thread) ...\n";
    auto out = capture_output("'" + peer + "' '" + frames_file.string() + "'");
    if (!out) return report_failure(out.error());
    nlohmann::json o3d;
    try {
      o3d = nlohmann::json::parse(*out);
    } catch (const std::exception& e) {
      return report_failure({std::string("Open3D bench printed no JSON: ") + e.what()});
    }
    const double o3d_ms = o3d.value("ms_per_frame", 0.0);
    result["open3d_ms_per_frame"] = o3d_ms;
    result["open3d_wall_ms_per_frame"] = o3d.value("wall_ms_per_frame", 0.0);
    result["open3d_stages_cpu"] = {{"odometry_ms", o3d.value("odometry_ms", 0.0)},
                                   {"integrate_ms", o3d.value("integrate_ms", 0.0)},
                                   {"raycast_ms", o3d.value("raycast_ms", 0.0)}};
    result["open3d_version"] = o3d.value("open3d_version", "");
    result["open3d_peak_rss_mb"] = o3d.value("peak_rss_mb", 0.0);
    result["open3d_tracked_frames"] = o3d.value("tracked_frames", 0);
    const double ours = result["ms_per_frame"].get<double>();
    result["speedup_vs_open3d"] = ours > 0 ? o3d_ms / ours : 0.0;
    // Open3D's own tracking accuracy on these frames (so the comparison is not against a
    // pipeline that lost track), in the same relative-pose terms as ours.
    if (!seq->camera_from_model.empty() && o3d.contains("poses_world_from_camera")) {
      Run o3d_run;
      for (const auto& p : o3d["poses_world_from_camera"]) {
        Eigen::Matrix4d m;
        for (int i = 0; i < 16; ++i) m(i / 4, i % 4) = p[i].get<double>();
        FrameReport r;
        r.fused = true;
        r.state = o3d_run.reports.empty() ? TrackingState::kStarted : TrackingState::kTracking;
        r.world_from_camera.rotation = Eigen::Quaterniond(m.block<3, 3>(0, 0)).normalized();
        r.world_from_camera.translation = m.block<3, 1>(0, 3) * 1000.0;  // m -> mm
        o3d_run.reports.push_back(r);
      }
      const PoseErrors e = pose_errors(*seq, o3d_run);
      result["open3d_pose_error_mm_max"] = e.max_mm;
      result["open3d_pose_error_deg_max"] = e.max_deg;
      result["open3d_pose_error_mm_mean"] = e.mean_mm;
      result["open3d_pose_error_deg_mean"] = e.mean_deg;
      if (options.flag("verbose")) {
        for (std::size_t k = 1; k < o3d_run.reports.size(); ++k) {
          Run prefix;
          prefix.reports.assign(o3d_run.reports.begin(), o3d_run.reports.begin() + k + 1);
          Sequence part;
          part.camera_from_model.assign(seq->camera_from_model.begin(),
                                        seq->camera_from_model.begin() + k + 1);
          std::fprintf(stderr, "  open3d frame %zu: max so far %.2f mm %.3f deg\n", k,
                       pose_errors(part, prefix).max_mm, pose_errors(part, prefix).max_deg);
        }
      }
    }
  }
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  result["peak_rss_mb"] = static_cast<double>(usage.ru_maxrss) / 1024.0;
  result["peak_rss_note"] =
      "whole facebooth process: TSDF volume, all frames held in memory, the synthetic renderer";
  result["threads"] = 1;
  result["budget_ms_per_frame"] = 8.0;
  result["budget_speedup"] = 5.0;
  std::cout << result.dump(2) << std::endl;
  return kExitOk;
}

}  // namespace

std::vector<Command> fusion_commands() {
  std::vector<OptionSpec> eval_options = {
      {"seeds", "N", "synthetic head-turn sequences (seeds first-seed..first-seed+N-1)", "5"},
      {"first-seed", "N", "first synthetic seed", "0"},
      {"frames", "N", "frames per sequence", "90"},
      {"scenario", "NAME",
       "realistic (a baseline, every part alone, then all: JSON scenarios.<part>; no real "
       "dump) or one part: identity|texture|hair|clutter|noise|unit (world_presets.hpp)",
       ""},
      {"synthetic", "URI", "base synthetic URI (seed and frames are appended)",
       "synthetic:motion=headturn"},
      {"frontal-frame", "N", "frame whose fused depth is scored", "0"},
      {"png", "PATH", "error map of the first seed (raw vs fused, mm colour scale)",
       "fusion_error.png"},
      {"error-scale-mm", "MM", "top of the error map's colour scale", "2"},
      {"mesh", "PATH", "write the first seed's fused mesh as PLY (empty: none)", ""},
      {"real", "PATH", "real fakenect dump (directory or .tar.xz), or off", FB_REAL_DUMP_DEFAULT},
      {"real-box", "detect|kiosk|X,Y,W,H", "face box for the real dump (as --box)", "detect"},
      {"real-mesh", "PATH", "PLY mesh written from the real dump", "fusion_real_mesh.ply"},
      {"verbose", "", "per-frame tracking state and stage times on stderr", ""},
      {"truth-poses", "", "diagnosis: fuse at the ground-truth poses instead of tracking", ""},
      {"json", "", "print JSON (the only output format; accepted for symmetry)", ""},
  };
  std::vector<OptionSpec> bench_options = {
      {"frames", "N", "frames of the synthetic head turn", "90"},
      {"seed", "N", "synthetic seed", "0"},
      {"camera", "URI", "time these frames instead (any camera URI)", ""},
      {"repeats", "N",
       "runs per configuration; ms_per_frame is the fastest, ms_per_frame_median and "
       "ms_per_frame_runs give the spread",
       "3"},
      {"verbose", "", "per-frame figures on stderr", ""},
      {"open3d", "PATH",
       "the facebooth-bench-open3d executable, or off (default: found next "
       "to facebooth or in the build tree)",
       ""},
      {"json", "", "print JSON (the only output format; accepted for symmetry)", ""},
  };
  for (const auto& o : fusion_option_specs()) {
    eval_options.push_back(o);
    bench_options.push_back(o);
  }
  return {
      {{"eval fusion",
        "score the face-box KinectFusion against synthetic ground truth and on the real dump",
        "Prints one JSON object on stdout: pose_error_mm_max and pose_error_deg_max (the head's "
        "pose relative to the first frame; mm = displacement at the face, the landmark "
        "centroid), camera_centre_error_mm_max (the same error at the camera centre, ~0.7 m "
        "away), fused_depth_mae_mm beside raw_depth_mae_mm (frontal frame, landmark-hull face "
        "region), fill_fraction, per-seed figures, and the real dump's run (lost frames, "
        "mesh). Writes the error map PNG and PLY meshes.",
        eval_options},
       run_eval_fusion},
      {{"bench fusion",
        "per-frame fusion time by stage (1 and 2 threads) beside Open3D on the same frames",
        "Prints one JSON object on stdout: ms_per_frame (ICP + integrate + ray-cast, one thread, "
        "CPU time), ms_per_frame_2threads (wall), open3d_ms_per_frame, speedup_vs_open3d, "
        "peak_rss_mb and the per-stage split; on a CPU with AVX2 also ms_per_frame_4lanes (the "
        "voxel update at the 4-lane width of the device's NEON).",
        bench_options},
       run_bench_fusion},
  };
}

}  // namespace fb::cli
