// VMC protocol (Virtual Motion Capture, OSC over UDP) sender for the tracking box, over liblo.
//
// Per frame, in order: `/VMC/Ext/Root/Pos "root" px py pz qx qy qz qw`, `/VMC/Ext/Bone/Pos
// "Head" px py pz qx qy qz qw`, then `/VMC/Ext/Blend/Val name value` for each of ARKit's 52
// curves (camelCase names, as VSeeFace / VMC receivers expect for "perfect sync"), then
// `/VMC/Ext/Blend/Apply`. Messages travel in OSC bundles (immediate time tag) of at most
// `max_bundle_bytes`, so one frame is a few datagrams that never need IP fragmentation.
//
// Coordinates (Unity, left-handed: +X avatar's right, +Y up, +Z avatar's forward; metres):
//  - Head: rotation of the head relative to facing the camera, mirrored from the model frame
//    (+X subject's left) by S = diag(-1, 1, 1): q_unity = (qx, -qy, -qz, qw); position 0
//    (a bone's position is local to its parent; receivers use the rotation).
//  - Root: translation of the head relative to the reference position (the first tracked
//    frame, or set_reference()), camera axes mapped as (-x, -y, -z) mm -> m; rotation identity.
// When the face is lost the last values are sent again (receivers keep a steady avatar).
#pragma once

#include <memory>
#include <string>
#include <string_view>

#include <Eigen/Core>

#include "algo/core/result.hpp"
#include "algo/tracking/arkit.hpp"

namespace fb {

inline constexpr int kVmcDefaultPort = 39539;

struct VmcOptions {
  std::string host = "127.0.0.1";
  int port = kVmcDefaultPort;
  int max_bundle_bytes = 1200;  // below a 1500-byte MTU with IP/UDP headers
  bool send_root = true;
};

// "HOST:PORT", "HOST" (default port) or ":PORT" (default host) into options.
Result<VmcOptions> parse_osc_destination(std::string_view text);

struct VmcPosePayload {
  Eigen::Vector3f head_position = Eigen::Vector3f::Zero();      // Unity metres (bone-local)
  Eigen::Vector4f head_rotation = Eigen::Vector4f(0, 0, 0, 1);  // qx qy qz qw, Unity
  Eigen::Vector3f root_position = Eigen::Vector3f::Zero();
  Eigen::Vector4f root_rotation = Eigen::Vector4f(0, 0, 0, 1);
};
// The pose values a frame is sent with (exposed for tests and the JSON formatter).
VmcPosePayload vmc_pose(const RigidPose& camera_from_model, const RigidPose& reference);

class VmcSender {
 public:
  static Result<std::unique_ptr<VmcSender>> open(const VmcOptions& options);
  ~VmcSender();
  VmcSender(const VmcSender&) = delete;
  VmcSender& operator=(const VmcSender&) = delete;

  // Sends one frame (blocking sendto; returns once the datagrams have left the socket).
  Result<void> send(const ArkitFrame& frame);
  void set_reference(const RigidPose& camera_from_model);

  const VmcOptions& options() const;
  long long datagrams_sent() const;
  long long messages_sent() const;

  struct State;

 private:
  explicit VmcSender(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;
};

}  // namespace fb
