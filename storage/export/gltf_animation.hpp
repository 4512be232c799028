// A glTF animation of a blendshape rig (issue 40 item 5: a take "applied in the exported
// animation"): one sampler input of the frames' times, a `weights` channel on the mesh's node
// (one weight per morph target per frame) and the head pose as `translation` and `rotation`
// channels on a parent node, all LINEAR; per-frame numbers a renderer may want beside them
// (the wrinkle map weights) go into the animation's extras.
//
// Coordinates: the rig is in the face model's frame (+X the subject's left, +Y up, +Z out of the
// face; the glb's mesh as encode_glb writes it, millimetres to metres), which is glTF's (+Y up,
// +Z toward the viewer). A take's head pose is camera_from_model in the depth camera's frame
// (+X right in the image, +Y down, +Z forward, mm). The scene is that camera's frame turned 180
// degrees about X: glTF (x, y, z) = camera (x, -y, -z) / 1000. So the scene's origin is the
// Kinect, which looks down -Z with +Y up as a glTF camera does, and a head facing the Kinect
// faces +Z, toward the viewer, about 0.7 m in front of the origin at z = -0.7.
#pragma once

#include <string>
#include <vector>

#include "algo/core/camera_model.hpp"
#include "algo/core/result.hpp"

namespace fb {

// Per-frame numbers for the animation's extras: extras[key] = {"description", "columns",
// "values": one row per frame, `decimals` decimals}.
struct GlbAnimationExtra {
  std::string key;
  std::string description;
  std::vector<std::string> columns;
  std::vector<float> values;  // frames x columns
  int decimals = 6;
};

struct GlbAnimation {
  std::string name;
  std::vector<float> times_s;  // per frame, seconds from the first frame (0), increasing
  std::vector<float> weights;  // frames x morph targets, the mesh's target order
  // The head node's pose per frame in the scene frame above (append_head_pose); both empty:
  // the head does not move.
  std::vector<float> translations_m;  // 3 per frame
  std::vector<float> rotations;       // 4 per frame, x y z w, unit length
  std::vector<GlbAnimationExtra> extras;
};

// Appends a frame's head pose (camera_from_model, mm) in the scene frame, its quaternion in the
// previous frame's hemisphere (so interpolating between frames takes the short way round).
void append_head_pose(const RigidPose& camera_from_model, GlbAnimation& animation);
// The scene from a pose's camera frame: (x, y, z) -> (x, -y, -z), mm -> m.
RigidPose scene_from_camera_pose(const RigidPose& camera_from_model);

// Fails, saying which frame and what, when the sizes do not match `targets` morph targets, a
// time does not increase, or a value is not finite (glTF has no place for NaN).
Result<void> check_animation(const GlbAnimation& animation, int targets);

}  // namespace fb
