// The `synthetic` camera backend: renders the face model (chosen identity, expression weights
// and head-pose track) in front of a wall through the Kinect v1 sensor model
// (algo/render/kinect_sensor.hpp) and emits per-frame ground truth (FrameTruth).
//
// URI: synthetic:seed=3,expr=jawOpen:0.6+mouthSmile_L,motion=headturn|static,frames=90,
//      anim=expressive (jaw open, smile, blinks, brows up as 5 s of smooth bumps, repeated),
//      stall_after=N, fail_after=N (fault injection: the stream stalls or fails after N frames),
//      realtime=1 (frames arrive on the sensor's 30 fps clock, rendered ahead on a thread:
//      render_ahead.hpp; a consumer that falls behind loses frames, as with a real Kinect),
//      distance=700,noise=on|off,background=1200|off,identity=random|neutral,
//      unit=SEED|reg_dx=PX,reg_dy=PX,reg_rot=DEG,depth_scale=S,calibrated=0|1,
//      world=realistic|identity|texture|hair|clutter|noise|unit and the world's own keys
//      (displace, asym, id_scale, id_extreme, texture, tone, light, hair, beard, torso, desk,
//      hand, hand_pass, offset_x, offset_y, block_noise, block_px, speckle; world_presets.hpp)
//      or target=checkerboard,board=9x6:25mm,... (a calibration board, board_scene.hpp)
// Defaults: seed 0, neutral expression, headturn, 90 frames, 700 mm, noise on, wall at 1200 mm,
// random identity (N(0, 1) per mode from the seed), no world options (synthetic_world.hpp:
// out-of-span identities, texture, hair, clutter, realistic sensor noise; all off by default).
//
// Scene and conventions (all documented choices):
//  - Head pose: camera_from_model = T * R_flip * R_y(yaw) * R_x(pitch). R_flip (180 deg about x)
//    turns the model frame (+X subject's left, +Y up, +Z out of the face) into the camera frame
//    (x right, y down, z forward) with the face towards the camera. The head rotates about the
//    model origin (inside the head, behind the face, like a neck pivot); T puts the centroid of
//    the 68 landmarks of the rest pose at (0, 0, distance). "headturn": yaw = A_yaw sin(2 pi t /
//    P), pitch = A_pitch sin(4 pi t / P), A = 30 / 15 deg, P = 3 s, t = frame / 30 s.
//  - The model's skin mesh is open at the eyes, the mouth and the neck. The holes are capped
//    with triangle fans: eyes flat and dark, the mouth recessed 15 mm (a dark red cavity), the
//    neck flat, so the depth shows no see-through holes.
//  - Wall: a plane facing the camera at `background_mm`, fixed in the camera frame.
//  - Sensor: KinectSensorModel with KinectCalibration::defaults() (see kinect_sensor.hpp).
//    noise=off turns off the Gaussian disparity noise only; quantisation, projector shadow and
//    the dropouts at silhouettes and grazing angles stay (they are part of what a Kinect
//    delivers). With noise=off every measured pixel is raw_to_mm(mm_to_raw(round(z))).
//  - Colour image: Lambertian + ambient shading of per-vertex albedo (skin, darker brows, red
//    lips, dark eyes, painted from the landmark neighbourhoods on the rest-pose mesh). It is put
//    into the colour camera through the registration: every depth pixel with a noiseless
//    surface is mapped with KinectRegistration::depth_to_color (at its rounded noiseless mm)
//    and splatted to the nearest colour pixel with a z-test; colour pixels no depth pixel
//    reached are filled from their neighbours (two 3x3 passes) and the rest get the wall
//    colour. Round-to-nearest keeps the colour content at the geometric positions, so
//    landmarks_color_px (interpolated depth_to_color) matches the image; libfreenect-style
//    registered depth truncates x and so sits up to one pixel left of it, as with a real device.
//  - Time: frame i has host time i / 30 s (depth and colour alike) and device timestamps
//    i * 2,000,000 ticks of the 60 MHz clock (wrapping at 2^32). next_frame() renders on demand
//    and ignores the timeout (no pacing), except with realtime=1: then a thread renders ahead
//    and next_frame() waits for the frame's sensor time; truth() then has no noiseless depth and
//    sensor_frame() / material_pixels() belong to the render thread (not to be read).
//  - Determinism: everything random (identity draw, noise, dropouts) comes from counter-based
//    hashes of the seed and frame index, so a seed gives bit-identical frames on a given build.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "algo/facemodel/face_model.hpp"
#include "algo/guide/guide_expressions.hpp"
#include "algo/render/kinect_sensor.hpp"
#include "drivers/camera/camera_backend.hpp"
#include "sim/camera/frame_truth.hpp"
#include "sim/camera/render_ahead.hpp"
#include "sim/camera/synthetic_world.hpp"

namespace fb {

enum class SyntheticMotion {
  kHeadTurn,  // yaw/pitch sinusoids (see above)
  kStatic,    // frontal, no motion
};

struct SyntheticOptions {
  std::uint64_t seed = 0;
  // Identity coefficients in sigma units; unset = one N(0, 1) draw per mode from `seed`.
  std::optional<std::vector<float>> identity_coeffs;
  // One weight per model expression (shorter = the rest are zero).
  std::vector<float> expression_weights;
  // Optional per-frame expression weights; when non-empty, frame i uses
  // expression_track[min(i, size - 1)] instead of `expression_weights`.
  std::vector<std::vector<float>> expression_track;
  // This subject's own expression shapes, same layout as FaceModel::expression_basis (deltas from
  // the neutral, expression_count blocks of 3 * vertex_count); empty = the model's generic ones.
  // A subject whose expressions are not the generic deltas (e.g. the generic ones deformation-
  // transferred onto its identity) gives the rigging a personal signal to recover.
  std::vector<float> personal_expression_basis;

  SyntheticMotion motion = SyntheticMotion::kHeadTurn;
  double yaw_amplitude_deg = 30.0;
  double pitch_amplitude_deg = 15.0;
  double motion_period_s = 3.0;
  // Optional explicit head poses; when non-empty, frame i uses
  // camera_from_model_track[min(i, size - 1)] and `motion`/`distance_mm` are ignored.
  std::vector<RigidPose> camera_from_model_track;

  int frame_count = 90;
  // Deliver on the sensor's clock, rendering ahead on a thread (render_ahead.hpp).
  bool realtime = false;
  // Fault injection (-1 = off): after this many frames the stream stalls (next_frame() times
  // out from then on, as a stalled USB stream does) or fails (an error, as an unplugged one).
  long long stall_after = -1;
  long long fail_after = -1;
  double distance_mm = 700.0;     // depth of the rest-pose landmark centroid
  double background_mm = 1200.0;  // wall depth; <= 0 for no wall (empty background)

  KinectSensorOptions sensor;  // noise=off sets sensor.depth_noise = false
  // The unit's true calibration: depth and colour are rendered through it.
  KinectCalibration calibration = KinectCalibration::defaults();
  // What the camera reports as CameraInfo::calibration; unset = `calibration` (a calibrated
  // unit). A decalibrated unit (`unit=SEED` or the reg_*/depth_scale keys) renders through its
  // own correction and reports the plain defaults, as a Kinect without a device.json does.
  std::optional<KinectCalibration> reported_calibration;

  // The realistic world's options (synthetic_world.hpp); all off by default.
  SyntheticWorld world;

  Rgb8 wall_color{178, 180, 172};
  // Reported as CameraInfo::uri; empty = "synthetic:seed=N".
  std::string uri;
};

// A seeded unit-to-unit variation of a Kinect v1: registration shift up to +-20 px in x and y,
// rotation up to +-1 deg, depth scale within +-5 % and an inverse-depth offset within
// +-0.02 /m (all uniform). Seed 0 is the identity.
RegistrationCorrection random_unit_correction(std::uint64_t seed);

// The camera controls it takes (camera_controls.hpp): expression (the `expr=` syntax below),
// motion (headturn|static), frames (the take length) and realtime (0|1). Each overrides the URI key
// of the same meaning; faceboothd sets all three for a take of the guide's expression.
inline constexpr std::string_view kSyntheticControls = "expression,motion,frames,realtime";

// Parses the URI argument list (after `synthetic:`) and the controls into options. Unknown keys
// and bad values are errors that list what is accepted.
Result<SyntheticOptions> parse_synthetic_options(std::string_view arguments, const FaceModel& model,
                                                 const CameraControls& controls = {});

// Parses `expr=` values: `neutral`, or `name[:weight]` terms joined by '+', e.g.
// `jawOpen:0.6+mouthSmile_L` or `smile+eyes_closed:0.5` (weight defaults to 1). A name is a
// FaceModel expression name or, when `guide` is given, a guide expression (its recipe scaled
// by the weight). Returns one weight per model expression.
Result<std::vector<float>> parse_expression_spec(std::string_view spec, const FaceModel& model,
                                                 const GuideSet* guide = nullptr);

class SyntheticCamera : public DepthCamera, public GroundTruthCamera {
 public:
  ~SyntheticCamera() override;

  const CameraInfo& info() const override;
  Result<void> start() override;
  void stop() override;
  Result<FrameStatus> next_frame(RgbdFrame& frame, std::chrono::milliseconds timeout) override;
  const FrameTruth* truth() const override;
  // With realtime=1 and started: what the render thread did (frames late, overwritten, lead).
  std::optional<RenderAhead::Stats> realtime_stats() const;

  const SyntheticOptions& options() const;
  // Sensor-model output of the last frame, including why each missing pixel is missing.
  const SensorFrame& sensor_frame() const;
  // Hair and beard weights per depth pixel of the last frame (empty without hair or beard).
  std::span<const MaterialPixel> material_pixels() const;
  // Rest-pose (no expression track) mesh in model coordinates, incl. hole caps, and its triangles.
  std::span<const Eigen::Vector3f> model_vertices() const;
  std::span<const std::uint32_t> model_triangles() const;
  // The surface colour (linear 0..1 RGB, before lighting) the colour image shows at a point of
  // triangle `t` of model_triangles() (barycentric weights of its 2nd and 3rd corner): the
  // texture an atlas built from the frames should recover (eval texture).
  Eigen::Vector3f surface_albedo(int t, float b1, float b2) const;

  struct State;

 private:
  explicit SyntheticCamera(std::unique_ptr<State> state);
  friend Result<std::unique_ptr<SyntheticCamera>> make_synthetic_camera(const FaceModel&,
                                                                        const SyntheticOptions&);
  std::unique_ptr<State> state_;
};

// Builds a synthetic camera. The camera copies what it needs from `model` (it keeps no
// reference). Fails on inconsistent options (bad sizes, frame_count < 1, distance out of range).
Result<std::unique_ptr<SyntheticCamera>> make_synthetic_camera(const FaceModel& model,
                                                               const SyntheticOptions& options);

// Same, with the default face model asset (load_face_model()).
Result<std::unique_ptr<SyntheticCamera>> make_synthetic_camera(const SyntheticOptions& options);

// The backend the camera module exports (camera_module.cpp; drivers/camera/camera_plugin.hpp).
CameraBackend synthetic_camera_backend();

}  // namespace fb
