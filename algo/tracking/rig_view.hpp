// A stored subject rig (a neutral and named full-mesh blendshapes, as storage keeps them) seen
// as the tracker's TrackerRig: which of the face model's fitting shapes each named shape is.
// Shared by the host's `track --rig-from-store` and the device daemon's tracking mode.
#pragma once

#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "algo/facemodel/face_model.hpp"
#include "algo/tracking/arkit.hpp"
#include "algo/tracking/face_tracker.hpp"

namespace fb {

// The fitting shape a rig shape's name stands for: a model expression name (eyeBlink_L), or
// the ARKit or Live Link name (eyeBlinkLeft, EyeBlinkLeft) of a curve made of exactly one
// model shape. -1 for anything else: unknown names, browInnerUp and cheekPuff (each the mean of
// two model shapes), tongueOut (none), and the model's shapes that are not fitted.
int fitting_shape_for_name(const FaceModel& model, const ArkitMapping& mapping,
                           std::string_view name);

// The rig's shapes with a fitting shape, as spans into `shapes` (which must outlive the view);
// the others are left out. Sizes are not checked here: FaceTracker::set_rig() does that.
TrackerRig tracker_rig_view(std::span<const float> neutral, std::span<const std::string> names,
                            std::span<const std::vector<float>> shapes, const FaceModel& model,
                            const ArkitMapping& mapping);

}  // namespace fb
