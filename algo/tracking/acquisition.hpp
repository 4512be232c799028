// Where to look for the face on the first frame and after a loss: candidate start poses, best
// evidence first (an engine; FaceTracker runs ICP from each and takes the first good fit).
#pragma once

#include <array>

#include "algo/core/image.hpp"
#include "algo/core/rigid_pose.hpp"
#include "algo/tracking/subject_rig.hpp"
#include "algo/tracking/tracker_geometry.hpp"
#include "algo/tracking/tracker_options.hpp"

namespace fb {

struct StartPoses {
  std::array<RigidPoseF, 5> poses;
  int count = 0;
  bool from_landmarks = false;  // poses[0] is from the landmarks
};

// A pose from the landmarks (detection on the colour image, lifted with the depth), the last
// good pose (a short occlusion; null: none), and a frontal face on the nearest surface (depth
// detection) at three yaws.
StartPoses start_poses(const SubjectRig& rig, const TrackerCamera& camera,
                       const Image<float>& smoothed, const TrackLandmarks* landmarks,
                       const RigidPoseF* last_good, float min_depth_mm,
                       const AcquireOptions& options);

// The median reprojection error (px) of the model's interior landmarks at pose p against the
// detected ones; 1e9 with fewer than 10.
float landmark_error_px(const SubjectRig& rig, const TrackerCamera& camera, const RigidPoseF& p,
                        const TrackLandmarks& landmarks);

}  // namespace fb
