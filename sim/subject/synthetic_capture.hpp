// Synthetic captures for the eval commands (eval fit, eval rig): a synthetic head-turn take of a
// known subject -> KinectFusion -> fused frontal depth, with the ground truth of frame 0, and the
// fit target built from it. Shared by the lab's eval fit and eval rig (sim/lab).
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <random>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "algo/core/camera_model.hpp"
#include "algo/core/image.hpp"
#include "algo/core/result.hpp"
#include "algo/facemodel/face_model.hpp"
#include "algo/fitting/face_fit.hpp"
#include "algo/fusion/face_fusion.hpp"
#include "algo/guide/guide_expressions.hpp"
#include "algo/landmarks/landmark_detector.hpp"
#include "algo/sensor/kinect_calibration.hpp"
#include "host/cli/guide_files.hpp"
#include "sim/camera/synthetic_camera.hpp"
#include "sim/subject/unit_calibration.hpp"

namespace fb::cli {

// One synthetic capture: a fused frontal depth map, its colour frame and the truth.
struct Capture {
  PinholeIntrinsics intrinsics;
  KinectCalibration calibration;
  SurfaceView fused;
  Image<float> confidence;  // of the fused depth: the take's frames' agreement (view_consistency)
  ColorImage color;         // frame 0
  std::vector<ColorImage> colors;  // every frame (for landmark timing), when kept
  std::vector<Eigen::Vector2d> truth_color_px;
  std::vector<Eigen::Vector2d> truth_depth_px;
  Image<float> noiseless;         // rendered depth of frame 0 (diagnostics: --depth noiseless)
  RigidPose truth_pose;           // camera_from_model of frame 0
  std::vector<float> truth_mesh;  // model frame
  int fused_frames = 0;
  int dropped_frames = 0;  // frames fusion could not follow (lost): not fused, counted
  FaceBox box;             // the face box of frame 0 (depth image) fusion started in
  std::string box_source;  // "dlib" (detected on frame 0's colour image) or "fixed"
  std::string box_note;    // why the fixed box was used, when it was
  double fusion_ms = 0;
  // With keep_frames: every frame as delivered, and the camera that rendered them (its
  // painted skin is the truth of eval texture).
  std::vector<RgbdFrame> frames;
  std::shared_ptr<const SyntheticCamera> camera;
};

// `personal_expression_basis`: the subject's own expression shapes (SyntheticOptions), or empty
// for the model's generic ones. `world`: a scenario of the realistic synthetic world
// (world_presets.hpp) for subject `world_seed`, or empty for the plain camera. `unit`: the
// registration a decalibrated unit (the unit part) is used with (unit_calibration.hpp).
// `face_detector`: the face box comes from dlib on frame 0's colour image, lifted through the
// registration (face_region_box.hpp), as on the device; null or no face found: the kiosk's
// fixed rectangle (box_note says why).
Result<Capture> capture(const FaceModel& model, const std::vector<float>& identity,
                        const std::vector<float>& weights, std::uint64_t seed, int frames,
                        bool keep_colors, std::span<const float> personal_expression_basis = {},
                        std::string_view world = {}, std::uint64_t world_seed = 0,
                        UnitCalibration unit = UnitCalibration::kSelfCalibrated,
                        LandmarkDetector* face_detector = nullptr, bool keep_frames = false);

// A fit's model frame -> the capture's true model frame: truth_pose^-1 * the fit's
// camera_from_model (both of frame 0). Fits are scored against the truth through it.
RigidPose fitted_to_truth(const Capture& c, const RigidPose& fitted_camera_from_model);

// The fit target of a capture: colour-image landmarks lifted with the registration and the
// fused depth (or, for diagnostics, the noiseless rendering), with the skin map of frame 0's
// colour unless `skin` is false (an A/B of the skin map).
Result<FitTarget> make_fit_target(const Capture& c, std::span<const Eigen::Vector2d> color_px,
                                  bool noiseless_depth, bool skin = true);

// Gaussian pixel noise (sigma per axis) on landmark positions.
std::vector<Eigen::Vector2d> noisy(const std::vector<Eigen::Vector2d>& px, double sigma,
                                   std::mt19937_64& rng);

}  // namespace fb::cli
