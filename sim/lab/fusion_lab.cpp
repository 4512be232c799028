// facebooth-lab eval fusion | bench fusion: what both commands share (fusion_lab.hpp).
#include "sim/lab/fusion_lab.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "host/cli/frame_open.hpp"
#include "host/cli/tracker_setup.hpp"
#include "sim/camera/frame_truth.hpp"

namespace fb::cli::fusion_lab {
namespace {

Result<FaceBox> parse_box(const std::string& text, const PinholeIntrinsics& k) {
  if (text.empty() || text == "kiosk") return default_face_box(k.width, k.height);
  int x = 0, y = 0, width = 0, height = 0;
  char c1 = 0, c2 = 0, c3 = 0;
  std::istringstream in(text);
  if (!(in >> x >> c1 >> y >> c2 >> width >> c3 >> height) || c1 != ',' || c2 != ',' || c3 != ',' ||
      width <= 0 || height <= 0)
    return fail("--box must be X,Y,W,H in depth-image pixels, e.g. 220,120,200,240 (got '" + text +
                "')");
  FaceBox box;
  box.rect = PixelRect::from_size(x, y, width, height);
  return box;
}

}  // namespace

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
      {"below-chin-mm", "MM",
       "with a detected face, depth further below the chin than this (along the face's axis, in "
       "the head's frame) is not fused; 0 = no cut",
       "20"},
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
                      {"x", c.box.rect.x0},
                      {"y", c.box.rect.y0},
                      {"width", c.box.rect.width()},
                      {"height", c.box.rect.height()}};
  if (c.box.face_depth_mm > 0.0f) j["face_depth_mm"] = c.box.face_depth_mm;
  if (c.box.down.squaredNorm() > 0.0f) {
    j["chin_mm"] = {c.box.chin_mm.x(), c.box.chin_mm.y(), c.box.chin_mm.z()};
    j["down"] = {c.box.down.x(), c.box.down.y(), c.box.down.z()};
  }
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
  auto below_chin = options.get_double("below-chin-mm");
  if (!below_chin) return below_chin.failure();
  o.below_chin_mm = static_cast<float>(*below_chin);
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

Result<Run> run_fusion(FaceFusion& fusion, const Sequence& seq, const FaceBox& box,
                       const FusionOptions& options, bool verbose, bool truth_poses) {
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

PoseErrors pose_errors(const Sequence& seq, const Run& run, bool verbose) {
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

std::string synthetic_uri(const std::string& base, int seed, long long frames) {
  std::string uri = base.empty() ? "synthetic:motion=headturn" : base;
  uri += (uri.find(':') == uri.size() - 1 ? "" : ",");
  return uri + "seed=" + std::to_string(seed) + ",frames=" + std::to_string(frames);
}

}  // namespace fb::cli::fusion_lab
