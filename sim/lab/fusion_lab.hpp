// facebooth-lab eval fusion | bench fusion, the parts both share (fusion_lab.cpp): frames held
// in memory, the face box, the fusion options and one run of the pipeline over the frames.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "algo/fusion/face_fusion.hpp"
#include "algo/landmarks/face_region_box.hpp"
#include "host/cli/commands.hpp"

namespace fb::cli::fusion_lab {

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

Result<Sequence> load_sequence(const std::string& uri, long long max_frames, int frontal);

// Options shared by both commands.
std::vector<OptionSpec> fusion_option_specs();
Result<FusionOptions> parse_fusion_options(const ParsedOptions& options);

// The face box a sequence is fused in, and where it came from.
struct BoxChoice {
  FaceBox box;
  std::string source;  // "dlib", "kiosk" or "given"
  std::string note;    // why detection gave way to the kiosk rectangle
};

// `text`: detect (or empty), kiosk, or X,Y,W,H. Detection loads dlib's model once into
// `detector`; without it, or without a face, the kiosk rectangle (the note says why).
Result<BoxChoice> choose_box(const std::string& text, const Sequence& seq,
                             std::optional<LandmarkDetector>& detector);
nlohmann::json box_json(const BoxChoice& c);

// Running the pipeline over a sequence.
struct Run {
  std::vector<FrameReport> reports;
  int fused = 0;
  int lost = 0;
  std::vector<int> lost_frames;
};

Result<Run> run_fusion(FaceFusion& fusion, const Sequence& seq, const FaceBox& box,
                       const FusionOptions& options, bool verbose = false,
                       bool truth_poses = false);

double angle_deg(const Eigen::Matrix3d& r);

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

PoseErrors pose_errors(const Sequence& seq, const Run& run, bool verbose = false);

// The synthetic URI of one seed: `base` (or a head turn) with seed= and frames= appended.
std::string synthetic_uri(const std::string& base, int seed, long long frames);

int run_eval_fusion(const ParsedOptions& options);   // fusion_eval.cpp
int run_bench_fusion(const ParsedOptions& options);  // fusion_bench.cpp

}  // namespace fb::cli::fusion_lab
