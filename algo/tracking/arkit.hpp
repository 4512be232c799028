// Apple ARKit's 52 blendshape names and the mapping from the face model's 53 fitting shapes:
// the one mapping every output uses (VMC/OSC stream, live JSON, Live Link CSV, glTF/OBJ exports
// with `--names arkit`).
//
// Order: Apple's, as ARFaceAnchor.BlendShapeLocation's documentation lists them (left eye, right
// eye, mouth and jaw, brows/cheeks/nose, tongue), which is also Unreal's EARFaceBlendShape and
// the Live Link Face network packet order: index i means the same curve everywhere in the
// project. Only the Live Link Face app's CSV files differ: they write JawRight before JawLeft and
// MouthRight before MouthLeft (kLiveLinkCsvOrder below).
//
// Mapping from the ICT FaceKit shapes (model frame: +X = subject's left, so "_L" = subject's
// left = ARKit "Left", which is also the subject's own left):
//  - NAME_L / NAME_R -> NAMELeft / NAMERight (e.g. eyeBlink_L -> eyeBlinkLeft), 48 shapes;
//  - unsided names map 1:1 (jawOpen, jawForward, jawLeft, jawRight, mouthClose, mouthFunnel,
//    mouthPucker, mouthLeft, mouthRight, mouthRollLower/Upper, mouthShrugLower/Upper);
//  - browInnerUp_L + browInnerUp_R -> browInnerUp and cheekPuff_L + cheekPuff_R -> cheekPuff:
//    an ARKit value v is the model's L = R = v, so a weight is the mean of the two halves and a
//    combined shape (exports) is the sum of the two halves' deltas;
//  - tongueOut has no model shape (the skin has no tongue): always 0, a zero target in exports;
//  - the 8 eyeLook* (gaze) curves are sent but stay near 0: the tracker holds them
//    (WeightSolverOptions::hold_gaze_shapes), as depth has no eyeballs and the 68 landmarks no irises;
//  - the model's 4 extras (cheekRaiser_L/R, PupilDilate_L/R) are not fitted and not sent.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "algo/core/camera_model.hpp"
#include "algo/core/result.hpp"
#include "algo/facemodel/face_model.hpp"

namespace fb {

inline constexpr int kArkitShapeCount = 52;

// camelCase ARKit names (as ARKit, VMC/VSeeFace and glTF exports use them), Apple's order.
extern const std::array<std::string_view, kArkitShapeCount> kArkitNames;
// The same curves (same index) with Live Link Face's capitalised names (EyeBlinkLeft ...).
extern const std::array<std::string_view, kArkitShapeCount> kLiveLinkNames;
// The Live Link Face app's CSV column order: CSV curve column k holds ARKit curve
// kLiveLinkCsvOrder[k]. Apple's order with JawRight/JawLeft and MouthRight/MouthLeft swapped, as
// the app writes them (tests/streaming/fixtures/livelink_face_header.csv).
extern const std::array<int, kArkitShapeCount> kLiveLinkCsvOrder;

// The ARKit curve a model shape name feeds ("eyeBlink_L" -> "eyeBlinkLeft", "browInnerUp_R" ->
// "browInnerUp"), or an empty string when it feeds none.
std::string arkit_name_of(std::string_view model_name);

// For every ARKit curve, up to two model expression indices averaged into it (-1 = unused).
struct ArkitMapping {
  std::array<std::array<int, 2>, kArkitShapeCount> sources{};

  // arkit[i] = mean of the model weights of its sources, clamped to [0, 1]; 0 without sources.
  void to_arkit(std::span<const float> model_weights,
                std::array<float, kArkitShapeCount>& arkit) const;
  // The inverse used for scoring and tests: each source gets the ARKit value.
  void to_model(const std::array<float, kArkitShapeCount>& arkit,
                std::span<float> model_weights) const;
};

// Builds the mapping from the model's fitting expression names; fails when a fitting shape has
// no ARKit curve or an ARKit curve (other than tongueOut) has no model shape.
Result<ArkitMapping> make_arkit_mapping(const FaceModel& model);
// The same from any list of shape names (a rig's). Names without an ARKit curve are an error
// unless `unmapped` is given, which then receives their indices.
Result<ArkitMapping> make_arkit_mapping(std::span<const std::string> shape_names,
                                        std::vector<int>* unmapped = nullptr);

// One tracked frame as the outputs (VMC, SSE, CSV) see it.
struct ArkitFrame {
  std::uint64_t index = 0;
  double time_s = 0.0;
  bool face_found = false;  // false: weights and pose hold the last good values
  // Something in front of the face hides this share of it (TrackReport::occluded_fraction);
  // `occluded` when that is over the tracker's report threshold.
  bool occluded = false;
  float occluded_fraction = 0.0f;
  std::array<float, kArkitShapeCount> weights{};
  // Head pose: camera_from_model (depth camera frame, mm), the filtered tracker output.
  RigidPose camera_from_model;
};

// Head rotation relative to the frontal pose, in the model frame (+X subject's left, +Y up,
// +Z out of the face): R_head = R_flip^T * R_camera_from_model, R_flip = 180 deg about x.
Eigen::Quaterniond head_rotation(const RigidPose& camera_from_model);

// Live Link Face head angles in radians: R_head = R_y(yaw) * R_x(pitch) * R_z(roll) in the model
// frame (the synthetic camera's yaw/pitch convention). yaw > 0: the subject turns to their left;
// pitch > 0: chin down; roll > 0: the head tilts towards the subject's right shoulder.
struct HeadAngles {
  double yaw = 0.0;
  double pitch = 0.0;
  double roll = 0.0;
};
HeadAngles head_angles(const Eigen::Quaterniond& head);
Eigen::Quaterniond head_from_angles(const HeadAngles& angles);

}  // namespace fb
