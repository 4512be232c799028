#include "algo/fusion/face_fusion.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>

#include <time.h>

namespace fb {
namespace {

// Wall and calling-thread CPU time; the CPU figure is what one core of the device would spend
// even when other processes compete for the host's cores.
struct Stopwatch {
  std::chrono::steady_clock::time_point wall;
  double cpu_ms;
  static double thread_cpu_ms() {
    timespec ts{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
  }
  Stopwatch() { restart(); }
  void restart() {
    wall = std::chrono::steady_clock::now();
    cpu_ms = thread_cpu_ms();
  }
  // Adds the time since the last restart to `wall_out` / `cpu_out` and restarts.
  void lap(double& wall_out, double& cpu_out) {
    wall_out +=
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - wall).count();
    cpu_out += thread_cpu_ms() - cpu_ms;
    restart();
  }
};

}  // namespace

FaceFusion::FaceFusion() : runner_(std::make_unique<ParallelRunner>(1)) {}
FaceFusion::~FaceFusion() = default;

Result<void> FaceFusion::reset(const PinholeIntrinsics& intrinsics, const FaceBox& face_box,
                               const FusionOptions& options) {
  configured_ = false;
  if (intrinsics.width < 16 || intrinsics.height < 16 || !(intrinsics.fx > 0.0) ||
      !(intrinsics.fy > 0.0))
    return fail(
        "fusion needs camera intrinsics with a positive focal length and an image of at "
        "least 16 x 16 pixels");
  const FaceBox box = face_box.clipped(intrinsics.width, intrinsics.height);
  if (box.rect.width() < 16 || box.rect.height() < 16)
    return fail("the face box (" + std::to_string(face_box.rect.x0) + "," +
                std::to_string(face_box.rect.y0) + " " + std::to_string(face_box.rect.width()) +
                "x" + std::to_string(face_box.rect.height()) +
                ") must cover at least 16 x 16 pixels of the " + std::to_string(intrinsics.width) +
                "x" + std::to_string(intrinsics.height) + " image");
  if (!(options.truncation_mm > 0.0f)) return fail("truncation must be positive");
  if (!(options.volume_size_mm > 0.0f)) return fail("the volume size must be positive");
  if (options.threads < 1 || options.threads > 16) return fail("threads must be 1 to 16");
  if (options.icp_level0_step < 1 || options.icp_level0_step > 2)
    return fail("icp_level0_step must be 1 or 2");
  if (!TsdfIntegrator::lanes_supported(options.integrate_lanes))
    return fail(
        "integrate_lanes must be 0 (automatic), 4, or 8 where the CPU has AVX2 (this one "
        "runs at most " +
        std::to_string(TsdfIntegrator::widest_lanes()) + ")");
  if (options.truncation_mm < 2.0f * options.volume_size_mm / options.volume_resolution)
    return fail("truncation must span at least 2 voxels (raise it or the resolution)");
  if (auto ok =
          volume_.reset(options.volume_resolution, options.volume_size_mm, Eigen::Vector3f::Zero());
      !ok)
    return ok;
  options_ = options;
  intrinsics_ = intrinsics;
  box_ = box;
  start_box_ = box;
  anchor_depth_ = 0.0f;
  chin_world_ = down_world_ = Eigen::Vector3f::Zero();
  if (runner_->parts() != options.threads)
    runner_ = std::make_unique<ParallelRunner>(options.threads);
  preprocessor_.configure(options_);
  tracker_.configure(options_);
  integrator_.configure(options_, volume_);
  ray_caster_.configure(options_);
  pyramid_.allocate(intrinsics, box.rect);
  model_.allocate(intrinsics, box.rect, options_.model_view_level);
  scratch_depths_.clear();
  scratch_depths_.reserve(static_cast<std::size_t>(box.rect.width()) * box.rect.height());
  last_good_ = RigidPoseF{};
  started_ = false;
  lost_ = false;
  configured_ = true;
  return success();
}

void FaceFusion::place_volume(const RigidPoseF& world_from_camera) {
  // The nearest part of the box is the face (nose, cheeks): take a low percentile of the depths
  // so background or shoulders do not pull the cube away, then centre the cube laterally on the
  // pixels near that depth and put its centre a fixed distance behind the face. With a detected
  // face only depths near its landmarks count: a hand, the chest or a desk nearer than the face
  // must not take the volume.
  const FaceBox& b = box_;
  const bool detected = b.face_depth_mm > 0.0f;
  float lo = detected ? b.face_depth_mm - options_.face_band_front_mm : 0.0f;
  float hi = detected ? b.face_depth_mm + options_.face_band_back_mm : options_.max_depth_mm;
  for (int pass = 0; pass < 2; ++pass) {
    scratch_depths_.clear();
    for (int y = b.rect.y0; y < b.rect.y1; ++y)
      for (int x = b.rect.x0; x < b.rect.x1; ++x)
        if (const float d = pyramid_.raw.at(x, y); d > 0.0f && d >= lo && d <= hi)
          scratch_depths_.push_back(d);
    if (!scratch_depths_.empty()) break;
    lo = 0.0f;  // no depth near the detected face's: the box's nearest surface after all
    hi = options_.max_depth_mm;
  }
  const std::size_t nth = static_cast<std::size_t>(
      std::clamp(options_.near_percentile, 0.0f, 1.0f) * (scratch_depths_.size() - 1));
  std::nth_element(scratch_depths_.begin(), scratch_depths_.begin() + nth, scratch_depths_.end());
  const float near = scratch_depths_[nth];
  const float face_depth_band = 0.5f * options_.volume_size_mm;
  const LevelIntrinsics k = LevelIntrinsics::from(intrinsics_);
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  int count = 0;
  for (int y = b.rect.y0; y < b.rect.y1; ++y)
    for (int x = b.rect.x0; x < b.rect.x1; ++x) {
      const float d = pyramid_.raw.at(x, y);
      if (d <= 0.0f || d < lo || d > near + face_depth_band) continue;
      sum += Eigen::Vector3d((x - k.cx) / k.fx * d, (y - k.cy) / k.fy * d, d);
      ++count;
    }
  Eigen::Vector3f centre = (sum / std::max(count, 1)).cast<float>();
  centre.z() = near + options_.volume_center_behind_face_mm;
  volume_.set_origin(world_from_camera.apply(centre) -
                     Eigen::Vector3f::Constant(0.5f * volume_.size_mm()));
  // What the box follows: the face surface behind the box's centre (the landmarks' depth, or
  // about the eyes' depth behind the nearest surface, the nose).
  const float z = detected ? b.face_depth_mm : near + 30.0f;
  const float u = static_cast<float>(b.rect.x0) + 0.5f * static_cast<float>(b.rect.width() - 1);
  const float v = static_cast<float>(b.rect.y0) + 0.5f * static_cast<float>(b.rect.height() - 1);
  anchor_world_ =
      world_from_camera.apply(Eigen::Vector3f((u - k.cx) / k.fx * z, (v - k.cy) / k.fy * z, z));
  anchor_depth_ = z;
}

void FaceFusion::set_chin_cut(const RigidPoseF& world_from_camera) {
  if (!started_) {
    // The detection's frame is the first fused one: the cut enters the world frame with it.
    const bool cut = start_box_.down.squaredNorm() > 0.0f && options_.below_chin_mm > 0.0f;
    chin_world_ = cut ? world_from_camera.apply(start_box_.chin_mm) : Eigen::Vector3f::Zero();
    down_world_ = cut ? Eigen::Vector3f(world_from_camera.r * start_box_.down.normalized())
                      : Eigen::Vector3f::Zero();
  }
  if (down_world_.squaredNorm() == 0.0f) {
    preprocessor_.clear_plane_gate();
    return;
  }
  // down . (R p + t - chin) > margin  <=>  (R^T down) . p > margin + down . (chin - t)
  preprocessor_.set_plane_gate(
      world_from_camera.r.transpose() * down_world_,
      options_.below_chin_mm + down_world_.dot(chin_world_ - world_from_camera.t));
}

FaceBox FaceFusion::box_at(const RigidPoseF& world_from_camera) const {
  if (!options_.box_follows_face || !(anchor_depth_ > 0.0f)) return start_box_;
  const Eigen::Vector3f p = world_from_camera.inverse().apply(anchor_world_);
  if (!(p.z() > 1.0f)) return start_box_;
  const LevelIntrinsics k = LevelIntrinsics::from(intrinsics_);
  const float s = anchor_depth_ / p.z();  // nearer face, larger box
  const float w = static_cast<float>(start_box_.rect.width()) * s;
  const float h = static_cast<float>(start_box_.rect.height()) * s;
  const float u = k.fx * p.x() / p.z() + k.cx, v = k.fy * p.y() / p.z() + k.cy;
  // The chin cut is not carried along: it entered the world frame with the first frame.
  FaceBox out;
  out.rect =
      PixelRect::from_size(static_cast<int>(std::lround(u - 0.5f * (w - 1.0f))),
                           static_cast<int>(std::lround(v - 0.5f * (h - 1.0f))),
                           static_cast<int>(std::lround(w)), static_cast<int>(std::lround(h)))
          .clipped(intrinsics_.width, intrinsics_.height);
  out.face_depth_mm = start_box_.face_depth_mm > 0.0f ? p.z() : 0.0f;
  // A face leaving the image keeps the last box that still holds a useful part of it.
  return out.rect.width() < 16 || out.rect.height() < 16 ? box_ : out;
}

void FaceFusion::cast_model(const RigidPoseF& pose) {
  // The model view covers the box the next frame will be read in (predicted from this pose).
  if (options_.box_follows_face) model_.move_box(box_at(pose).rect);
  // The frame just fused is the hint: raw depth at full resolution, the pyramid level otherwise.
  const Image<float>& hint = model_.first_level > 0 ? pyramid_.levels[model_.first_level].depth
                             : options_.integrate_filtered_depth ? pyramid_.levels[0].depth
                                                                 : pyramid_.raw;
  const bool hint_is_raw = model_.first_level == 0 && !options_.integrate_filtered_depth;
  ray_caster_.cast(volume_, pose, &hint, hint_is_raw, false, model_.levels[0], *runner_);
  subsample_model_levels(model_);
  model_.world_from_camera = pose;
  model_.valid = true;
}

FrameReport FaceFusion::process(const DepthImage& depth_mm, const RigidPose* known_pose) {
  FrameReport report;
  report.world_from_camera = last_good_.to_rigid();
  report.state = started_ ? TrackingState::kLost : TrackingState::kNotStarted;
  if (!configured_) {
    report.state = TrackingState::kBadInput;
    report.loss_reason = "fusion was not configured (reset() failed or was not called)";
    return report;
  }
  if (depth_mm.empty() || depth_mm.width != intrinsics_.width ||
      depth_mm.height != intrinsics_.height ||
      depth_mm.pixels.size() != static_cast<std::size_t>(depth_mm.width) * depth_mm.height) {
    report.state = TrackingState::kBadInput;
    report.loss_reason =
        depth_mm.empty() ? "empty depth frame" : "depth frame size differs from the camera's";
    return report;
  }
  Stopwatch t;
  if (started_ && options_.box_follows_face) {
    // This frame's box: where the face is at the last good pose (the motion of one frame is
    // small against the box's margins; a lost face is looked for where it was last).
    const FaceBox next = box_at(last_good_);
    if (next.rect != box_.rect) {
      pyramid_.move_box(next.rect);
      box_ = next;
    }
  }
  if (box_.face_depth_mm > 0.0f)  // a detected face: only depths near it are the face
    preprocessor_.set_depth_gate(
        std::max(options_.min_depth_mm, box_.face_depth_mm - options_.face_band_front_mm),
        std::min(options_.max_depth_mm, box_.face_depth_mm + options_.face_band_back_mm));
  set_chin_cut(started_ ? last_good_ : (known_pose ? RigidPoseF::from(*known_pose) : RigidPoseF{}));
  preprocessor_.run(depth_mm, pyramid_, *runner_);
  t.lap(report.times.preprocess_ms, report.cpu_times.preprocess_ms);
  report.valid_pixels = pyramid_.valid_pixels;
  const Image<float>& fuse_depth = pyramid_.fused;
  const LevelIntrinsics k0 = pyramid_.levels[0].k;

  if (!started_) {
    if (pyramid_.valid_pixels < options_.min_valid_pixels_to_start) {
      report.loss_reason = "too little valid depth in the face box to start fusion";
      return report;
    }
    last_good_ = known_pose ? RigidPoseF::from(*known_pose) : RigidPoseF{};
    place_volume(last_good_);
    report.integrated_bricks =
        integrator_.integrate(fuse_depth, k0, box_.rect, last_good_, volume_, *runner_);
    t.lap(report.times.integrate_ms, report.cpu_times.integrate_ms);
    cast_model(last_good_);
    t.lap(report.times.raycast_ms, report.cpu_times.raycast_ms);
    started_ = true;
    lost_ = false;
    report.state = TrackingState::kStarted;
    report.fused = true;
    report.world_from_camera = last_good_.to_rigid();
    return report;
  }

  if (pyramid_.valid_pixels < options_.min_inliers) {
    lost_ = true;
    report.loss_reason = "too little valid depth in the face box";
    return report;
  }
  t.restart();
  IcpResult icp;
  if (known_pose) {
    // Poses given by the caller (ground truth, or a tracker elsewhere): fuse without ICP.
    icp.world_from_camera = RigidPoseF::from(*known_pose);
    icp.solved = true;
    icp.inliers = icp.candidates = pyramid_.valid_pixels;
  } else {
    icp = tracker_.track(pyramid_, model_, last_good_, *runner_);
  }
  t.lap(report.times.track_ms, report.cpu_times.track_ms);
  report.inliers = icp.inliers;
  report.rms_mm = icp.rms_mm;
  report.iterations = icp.iterations;
  // Plausibility in the head's terms: how far the volume centre (the head) moved relative to
  // the camera, and by how much the view turned; a head turn of a few degrees moves the camera
  // centre by many centimetres relative to the head, so the camera centre is not the measure.
  const RigidPoseF delta = last_good_.inverse() * icp.world_from_camera;
  const Eigen::Vector3f head =
      volume_.origin() + Eigen::Vector3f::Constant(0.5f * volume_.size_mm());
  const float moved =
      (icp.world_from_camera.inverse().apply(head) - last_good_.inverse().apply(head)).norm();
  const float turned =
      std::acos(std::clamp((delta.r.trace() - 1.0f) * 0.5f, -1.0f, 1.0f)) * 180.0f / M_PI;
  const char* reason = nullptr;
  if (!icp.solved)
    reason = "ICP was ill-conditioned (too little surface in view)";
  else if (icp.inliers < options_.min_inliers ||
           icp.inliers < options_.min_inlier_fraction * static_cast<float>(icp.candidates))
    reason = "too few ICP inliers (the face left the box or the model)";
  else if (icp.rms_mm > options_.max_rms_mm)
    reason = "ICP residual too large";
  else if (moved > options_.max_frame_translation_mm || turned > options_.max_frame_rotation_deg)
    reason = "implausible motion between frames";
  if (reason) {
    lost_ = true;
    report.loss_reason = reason;
    return report;
  }
  last_good_ = icp.world_from_camera;
  t.restart();
  report.integrated_bricks =
      integrator_.integrate(fuse_depth, k0, box_.rect, last_good_, volume_, *runner_);
  t.lap(report.times.integrate_ms, report.cpu_times.integrate_ms);
  t.restart();
  cast_model(last_good_);
  t.lap(report.times.raycast_ms, report.cpu_times.raycast_ms);
  report.state = lost_ ? TrackingState::kRecovered : TrackingState::kTracking;
  lost_ = false;
  report.fused = true;
  report.world_from_camera = last_good_.to_rigid();
  return report;
}

void FaceFusion::render(const RigidPose& world_from_camera, SurfaceView& out) {
  const FaceBox box = box_for(world_from_camera);
  if (render_level_.depth.width != intrinsics_.width ||
      render_level_.depth.height != intrinsics_.height)
    render_level_.allocate(LevelIntrinsics::from(intrinsics_), box.rect);
  else
    render_level_.move_box(box.rect);
  std::fill(render_level_.depth.pixels.begin(), render_level_.depth.pixels.end(), 0.0f);
  ray_caster_.cast(volume_, RigidPoseF::from(world_from_camera), nullptr, false, true,
                   render_level_, *runner_);
  out.depth_mm = render_level_.depth;
  out.normals = render_level_.normals;
}

SurfaceView FaceFusion::render(const RigidPose& world_from_camera) {
  SurfaceView out;
  render(world_from_camera, out);
  return out;
}

TriangleMesh FaceFusion::extract_mesh(const MeshOptions& options) const {
  return fb::extract_mesh(volume_, options);
}

}  // namespace fb
