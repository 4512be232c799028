// Synthetic tracking takes with ground truth, for `eval track` and `bench track`: a random
// identity (N(0, 1) per mode), smooth random expression-weight tracks over a handful of shapes
// (smoothstep between random keyframes, neutral for the first frames so the tracker can
// calibrate the identity), smooth head motion (yaw/pitch/roll sinusoids and a few cm of
// translation), Kinect sensor noise on. 2D landmarks are the ground truth plus Gaussian pixel
// noise. The occluder take composites a flat hand-sized plate into the scene and renders it
// through the Kinect sensor model (projector shadow, dropouts, noise); landmarks under it are
// misdetected. Every frame is rendered up front, so rendering is never part of a timing.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <numbers>
#include <string>
#include <vector>

#include "algo/core/result.hpp"
#include "algo/facemodel/face_model.hpp"
#include "sim/camera/synthetic_camera.hpp"
#include "sim/subject/unit_calibration.hpp"

namespace fb::cli {

inline constexpr double kDeg = 180.0 / std::numbers::pi;
inline constexpr double kLandmarkNoisePx = 1.5;
// Occluder take: landmarks under the plate move this far.
inline constexpr double kMisdetectionPx = 15.0;

struct TakeSpec {
  std::uint64_t seed = 1;
  int frames = 150;
  int active_shapes = 5;
  int neutral_frames = 20;  // calibration window + margin: the subject holds a neutral face
  bool occluder = false;
  bool noise = true;
  bool color = false;  // keep the colour images (for dlib landmarks; 0.9 MB a frame)
  // A scenario of the realistic synthetic world (world_presets.hpp) for this take's subject
  // (seeded by `seed`); empty = the plain camera.
  std::string world;
  // The registration a decalibrated unit (the unit part) is used with.
  UnitCalibration unit_calibration = UnitCalibration::kSelfCalibrated;
};

struct Take {
  SyntheticOptions options;
  std::vector<int> active;  // model shape indices with a non-zero track
  Eigen::Vector3d face_centre_model = Eigen::Vector3d::Zero();  // true identity, model frame
  // Occluder (camera frame): plate centre per frame (NaN = absent), size in mm.
  std::vector<Eigen::Vector3f> occluder_centre;
  float occluder_width = 90.0f, occluder_height = 110.0f;
  int occluder_first = -1, occluder_last = -1;  // frames with the plate over the face region
};

// One rendered frame held in memory (so rendering is never part of a timing).
struct TakeFrame {
  DepthImage depth;
  FrameTruth truth;
  std::vector<Eigen::Vector2f> landmarks;     // truth + noise, depth pixels
  int landmarks_misdetected = 0;              // under the occluder plate, moved onto it
  std::vector<std::uint8_t> occluded_shapes;  // per model shape: its region is under the plate
  bool occluder_on_face = false;
  ColorImage color;  // only when TakeSpec::color (dlib landmarks)
};

struct RenderedTake {
  Take take;
  PinholeIntrinsics intrinsics;
  KinectCalibration calibration;
  std::vector<TakeFrame> frames;
};

Result<RenderedTake> render_take(const FaceModel& model, const TakeSpec& spec);

}  // namespace fb::cli
