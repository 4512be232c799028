#include "algo/tracking/arkit.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

namespace fb {

const std::array<std::string_view, kArkitShapeCount> kArkitNames = {
    "eyeBlinkLeft",      "eyeLookDownLeft",    "eyeLookInLeft",
    "eyeLookOutLeft",    "eyeLookUpLeft",      "eyeSquintLeft",
    "eyeWideLeft",       "eyeBlinkRight",      "eyeLookDownRight",
    "eyeLookInRight",    "eyeLookOutRight",    "eyeLookUpRight",
    "eyeSquintRight",    "eyeWideRight",       "jawForward",
    "jawLeft",           "jawRight",           "jawOpen",
    "mouthClose",        "mouthFunnel",        "mouthPucker",
    "mouthLeft",         "mouthRight",         "mouthSmileLeft",
    "mouthSmileRight",   "mouthFrownLeft",     "mouthFrownRight",
    "mouthDimpleLeft",   "mouthDimpleRight",   "mouthStretchLeft",
    "mouthStretchRight", "mouthRollLower",     "mouthRollUpper",
    "mouthShrugLower",   "mouthShrugUpper",    "mouthPressLeft",
    "mouthPressRight",   "mouthLowerDownLeft", "mouthLowerDownRight",
    "mouthUpperUpLeft",  "mouthUpperUpRight",  "browDownLeft",
    "browDownRight",     "browInnerUp",        "browOuterUpLeft",
    "browOuterUpRight",  "cheekPuff",          "cheekSquintLeft",
    "cheekSquintRight",  "noseSneerLeft",      "noseSneerRight",
    "tongueOut"};

const std::array<std::string_view, kArkitShapeCount> kLiveLinkNames = {
    "EyeBlinkLeft",      "EyeLookDownLeft",    "EyeLookInLeft",
    "EyeLookOutLeft",    "EyeLookUpLeft",      "EyeSquintLeft",
    "EyeWideLeft",       "EyeBlinkRight",      "EyeLookDownRight",
    "EyeLookInRight",    "EyeLookOutRight",    "EyeLookUpRight",
    "EyeSquintRight",    "EyeWideRight",       "JawForward",
    "JawLeft",           "JawRight",           "JawOpen",
    "MouthClose",        "MouthFunnel",        "MouthPucker",
    "MouthLeft",         "MouthRight",         "MouthSmileLeft",
    "MouthSmileRight",   "MouthFrownLeft",     "MouthFrownRight",
    "MouthDimpleLeft",   "MouthDimpleRight",   "MouthStretchLeft",
    "MouthStretchRight", "MouthRollLower",     "MouthRollUpper",
    "MouthShrugLower",   "MouthShrugUpper",    "MouthPressLeft",
    "MouthPressRight",   "MouthLowerDownLeft", "MouthLowerDownRight",
    "MouthUpperUpLeft",  "MouthUpperUpRight",  "BrowDownLeft",
    "BrowDownRight",     "BrowInnerUp",        "BrowOuterUpLeft",
    "BrowOuterUpRight",  "CheekPuff",          "CheekSquintLeft",
    "CheekSquintRight",  "NoseSneerLeft",      "NoseSneerRight",
    "TongueOut"};

// Identity but for the two pairs the app writes right before left.
const std::array<int, kArkitShapeCount> kLiveLinkCsvOrder = {
    0,  1,  2,  3,  4,  5,  6,  7,  8,  9,  10, 11, 12, 13, 14, 16, 15, 17,
    18, 19, 20, 22, 21, 23, 24, 25, 26, 27, 28, 29, 30, 31, 32, 33, 34, 35,
    36, 37, 38, 39, 40, 41, 42, 43, 44, 45, 46, 47, 48, 49, 50, 51};

std::string arkit_name_of(std::string_view model_name) {
  std::string base(model_name);
  std::string side;
  if (base.size() > 2 && (base.ends_with("_L") || base.ends_with("_R"))) {
    side = base.back() == 'L' ? "Left" : "Right";
    base.resize(base.size() - 2);
  }
  // The merged pairs lose their side.
  std::string name = base == "browInnerUp" || base == "cheekPuff" ? base : base + side;
  // An ARKit name given as is (a rig already in ARKit names) maps to itself.
  if (std::find(kArkitNames.begin(), kArkitNames.end(), name) == kArkitNames.end()) return {};
  return name;
}

Result<ArkitMapping> make_arkit_mapping(const FaceModel& model) {
  return make_arkit_mapping(std::span<const std::string>(
      model.expression_names.data(), static_cast<std::size_t>(model.fitting_expression_count)));
}

Result<ArkitMapping> make_arkit_mapping(std::span<const std::string> shape_names,
                                        std::vector<int>* unmapped) {
  ArkitMapping mapping;
  for (auto& s : mapping.sources) s = {-1, -1};
  for (int j = 0; j < static_cast<int>(shape_names.size()); ++j) {
    const std::string& model_name = shape_names[static_cast<std::size_t>(j)];
    const std::string name = arkit_name_of(model_name);
    const auto it = std::find(kArkitNames.begin(), kArkitNames.end(), name);
    if (it == kArkitNames.end()) {
      if (unmapped != nullptr) {
        unmapped->push_back(j);
        continue;
      }
      return fail("tracking: model expression '" + model_name +
                  "' has no ARKit curve (expected ICT FaceKit names such as eyeBlink_L)");
    }
    auto& slot = mapping.sources[static_cast<std::size_t>(it - kArkitNames.begin())];
    if (slot[0] < 0) {
      slot[0] = j;
    } else if (slot[1] < 0) {
      slot[1] = j;
    } else {
      return fail("tracking: more than two model shapes map to ARKit '" + name + "'");
    }
  }
  for (int i = 0; i < kArkitShapeCount; ++i) {
    if (mapping.sources[i][0] < 0 && kArkitNames[i] != "tongueOut") {
      return fail("the shapes (" + std::to_string(shape_names.size()) +
                  " names) have none for ARKit '" + std::string(kArkitNames[i]) +
                  "' (expected the face model's ICT FaceKit names such as eyeBlink_L)");
    }
  }
  return mapping;
}

void ArkitMapping::to_arkit(std::span<const float> model_weights,
                            std::array<float, kArkitShapeCount>& arkit) const {
  for (int i = 0; i < kArkitShapeCount; ++i) {
    float sum = 0.0f;
    int count = 0;
    for (int s : sources[i]) {
      if (s < 0 || static_cast<std::size_t>(s) >= model_weights.size()) continue;
      sum += model_weights[static_cast<std::size_t>(s)];
      ++count;
    }
    arkit[i] = count ? std::clamp(sum / static_cast<float>(count), 0.0f, 1.0f) : 0.0f;
  }
}

void ArkitMapping::to_model(const std::array<float, kArkitShapeCount>& arkit,
                            std::span<float> model_weights) const {
  for (int i = 0; i < kArkitShapeCount; ++i) {
    for (int s : sources[i]) {
      if (s >= 0 && static_cast<std::size_t>(s) < model_weights.size()) {
        model_weights[static_cast<std::size_t>(s)] = arkit[i];
      }
    }
  }
}

Eigen::Quaterniond head_rotation(const RigidPose& camera_from_model) {
  const Eigen::Quaterniond flip(Eigen::AngleAxisd(std::numbers::pi, Eigen::Vector3d::UnitX()));
  return (flip.conjugate() * camera_from_model.rotation).normalized();
}

HeadAngles head_angles(const Eigen::Quaterniond& head) {
  // R = Ry(yaw) Rx(pitch) Rz(roll): R(1,2) = -sin(pitch), R(0,2) = sin(yaw) cos(pitch),
  // R(2,2) = cos(yaw) cos(pitch), R(1,0) = cos(pitch) sin(roll), R(1,1) = cos(pitch) cos(roll).
  const Eigen::Matrix3d r = head.normalized().toRotationMatrix();
  HeadAngles a;
  a.pitch = std::asin(std::clamp(-r(1, 2), -1.0, 1.0));
  a.yaw = std::atan2(r(0, 2), r(2, 2));
  a.roll = std::atan2(r(1, 0), r(1, 1));
  return a;
}

Eigen::Quaterniond head_from_angles(const HeadAngles& a) {
  return Eigen::AngleAxisd(a.yaw, Eigen::Vector3d::UnitY()) *
         Eigen::AngleAxisd(a.pitch, Eigen::Vector3d::UnitX()) *
         Eigen::AngleAxisd(a.roll, Eigen::Vector3d::UnitZ());
}

}  // namespace fb
