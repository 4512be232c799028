// Options and results of the face-box KinectFusion (FaceWarehouse section 3.1).
// Units: millimetres; camera coordinates follow OpenCV (x right, y down, z forward).
// The "world" frame is the depth camera frame of the first fused frame; every camera pose is
// world_from_camera (maps camera points into the world).
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "algo/core/camera_model.hpp"
#include "algo/core/image.hpp"
#include "algo/core/pixel_rect.hpp"

namespace fb {

// Where the face is in an image (the kiosk's on-screen rectangle or a detection), and what is
// known about its depth.
struct FaceBox {
  PixelRect rect;
  // Depth of the detected face in this box (median of its landmarks' depths), 0 = unknown. With
  // it the volume is placed on the face, not on the nearest surface (a hand, the chest, a desk).
  float face_depth_mm = 0.0f;
  // Where the face ends below, in the camera frame of the frame the face was found in: the
  // chin and the face's downward axis (nose bridge to chin). Fusion leaves out what lies more
  // than FusionOptions::below_chin_mm below the chin in the head's own frame: the neck and the
  // chest do not turn with the head. down = 0: no cut (the kiosk's fixed box).
  Eigen::Vector3f chin_mm = Eigen::Vector3f::Zero();
  Eigen::Vector3f down = Eigen::Vector3f::Zero();

  // The same box with its rectangle clipped to a w x h image.
  FaceBox clipped(int w, int h) const {
    FaceBox out = *this;
    out.rect = rect.clipped(w, h);
    return out;
  }
};

// The default configured rectangle of the kiosk: 200 x 240 px in the middle of a 640 x 480 view,
// which holds a face at 0.5-0.9 m.
FaceBox default_face_box(int width, int height);

struct FusionOptions {
  // --- Volume: a cube sized to the head ---
  float volume_size_mm = 300.0f;
  int volume_resolution = 256;  // voxels per side, a multiple of 8 (bricks of 8^3)
  // TSDF truncation: Kinect v1 depth noise is ~1.5 mm (sigma) at 0.7 m and disparity steps are
  // ~1.3 mm there, so +/-8 mm (about 7 voxels) holds the noise band with margin.
  float truncation_mm = 8.0f;
  // Running-average weight cap (at most 31, the voxel's 5 weight bits): beyond it each frame
  // enters with weight 1/32, an exponential average with the noise reduction of a 63-frame
  // mean, so a 3 s head turn (90 frames) is averaged and the model still adapts slowly.
  int max_weight = 31;
  // The volume centre sits behind the nearest face surface (percentile of depths in the box)
  // by this much, so the face and the sides of the head fit in the cube.
  float volume_center_behind_face_mm = 70.0f;
  float near_percentile = 0.10f;
  // Depths this far in front of / behind a detected face (FaceBox::face_depth_mm) are not the
  // face: a hand 130 mm in front, the chest, a desk.
  float face_band_front_mm = 80.0f;
  float face_band_back_mm = 150.0f;
  // With a detected face (FaceBox::down), depth further below the chin than this along the
  // face's axis is not fused: it keeps the jaw's underside and leaves out the neck and chest.
  float below_chin_mm = 20.0f;
  // The face box follows the fused pose: each frame's box is the first frame's box moved (and
  // scaled) with the face, predicted from the last good pose, so a face that turns or moves
  // stays in its box. false: the box stays where reset() put it.
  bool box_follows_face = true;

  // --- Depth gating and preprocessing ---
  float min_depth_mm = 300.0f;
  float max_depth_mm = 2500.0f;
  int bilateral_radius_px = 2;  // 5 x 5 kernel
  float bilateral_sigma_space_px = 1.5f;
  float bilateral_sigma_depth_mm = 6.0f;   // ~4 sigma of Kinect noise at face distance
  float normal_max_depth_jump_mm = 20.0f;  // neighbours further apart break the surface
  bool integrate_filtered_depth = false;   // KinectFusion integrates the raw depth
  // Pixels seen at more than this angle between surface normal and ray are not integrated (nor
  // are pixels without a normal: silhouettes, isolated points); 90 integrates everything. Their
  // depth noise along the ray is several mm, and the truncation band's asymmetry (samples far
  // behind the surface are dropped, those far in front clamped) turns it into a small bias.
  // Measured on synthetic head turns (3 seeds): 70 deg lowers the fused error by ~5 % but
  // raises the pose error by ~10 %, so it is off by default.
  float integrate_max_angle_deg = 90.0f;

  // --- Tracking (projective point-to-plane ICP, coarse to fine) ---
  // Iteration caps per level, level 0 = full resolution (each level also stops on convergence).
  // Measured on the synthetic head turns (5 seeds): caps of 8/5/4 (coarse/middle/fine) and 4/3/3
  // give the same pose and fused-depth errors (the remaining per-frame error is the frame's
  // noise, not convergence), and 4/3/3 evaluates a third fewer points.
  std::array<int, 3> icp_iterations = {3, 3, 4};
  float icp_distance_mm = 25.0f;  // association gate
  // Pyramid level the tracker's model view is ray-cast at: 1 = half resolution (a quarter of
  // the rays; projective association tolerates the ~1 px lateral offset on a smooth face),
  // 0 = full resolution. The frontal output of render() is always at full resolution.
  int model_view_level = 1;
  int icp_level0_step = 2;  // 1 = every full-resolution pixel, 2 = a checkerboard
  float icp_normal_angle_deg = 35.0f;
  float icp_huber_mm = 3.0f;    // robust weight: residuals beyond this get Huber weights
  float icp_converged = 1e-5f;  // stop a level when |increment| (rad + mm/1000) drops below
  // Loss detection: too few inliers, too large a residual, or a jump no head makes in 33 ms.
  int min_inliers = 800;
  float min_inlier_fraction = 0.30f;  // of the input points that project onto the model
  float max_rms_mm = 3.0f;
  float max_frame_translation_mm = 40.0f;  // of the head centre relative to the camera
  float max_frame_rotation_deg = 20.0f;
  int min_valid_pixels_to_start = 2000;

  // Vector width of the voxel update: 0 = the widest this CPU runs (8 lanes, a whole brick row,
  // on x86-64 with AVX2; 4 lanes elsewhere: SSE2, the device's NEON), or 4 / 8 to choose.
  int integrate_lanes = 0;

  // --- Threads: 1 = the device's single-core figure; 2 uses a second worker ---
  int threads = 1;
};

enum class TrackingState : std::uint8_t {
  kNotStarted,  // no usable frame yet (nothing fused)
  kStarted,     // this frame started the volume (pose = identity)
  kTracking,    // tracked and fused
  kLost,        // tracking failed on this frame: not fused, pose = last good pose
  kRecovered,   // tracked again after one or more lost frames, and fused
  kBadInput,    // empty or wrongly sized frame: ignored
};

const char* to_string(TrackingState state);

struct StageTimes {
  double preprocess_ms = 0.0;
  double track_ms = 0.0;
  double integrate_ms = 0.0;
  double raycast_ms = 0.0;
  double total_ms() const { return preprocess_ms + track_ms + integrate_ms + raycast_ms; }
};

struct FrameReport {
  TrackingState state = TrackingState::kNotStarted;
  bool fused = false;            // the frame was integrated into the volume
  RigidPose world_from_camera;   // tracked pose (the last good one when lost)
  int valid_pixels = 0;          // valid input depth in the face box
  int inliers = 0;               // ICP inliers at full resolution (last iteration)
  float rms_mm = 0.0f;           // ICP point-to-plane RMS of the inliers
  int iterations = 0;            // ICP iterations over all levels
  int integrated_bricks = 0;     // 8^3-voxel bricks visited by the integrator
  const char* loss_reason = "";  // empty unless state == kLost or kBadInput
  StageTimes times;              // wall clock
  StageTimes cpu_times;  // CPU time of the calling thread: the one-core cost even on a busy host
};

// A ray-cast view of the fused surface from one camera pose.
struct SurfaceView {
  Image<float> depth_mm;           // z in the camera frame, 0 = no surface
  Image<Eigen::Vector3f> normals;  // camera frame, unit, zero where no surface
};

struct TriangleMesh {
  std::vector<Eigen::Vector3f> vertices;  // world frame, mm
  std::vector<Eigen::Vector3f> normals;   // unit, pointing out of the surface
  std::vector<Eigen::Vector3i> triangles;
};

}  // namespace fb
