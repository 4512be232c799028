// Which of the face's samples and landmarks something in front of the face (a hand) hides on
// this frame. Hidden samples leave the pose, the weights and the robust scale: an occluder's
// residuals (centimetres) would otherwise inflate the MAD and so the Tukey cut-off, and the face
// samples along its rim (mixed depths, the projector shadow's edge) would pass the cut-off and
// drag both. Made once per frame from the predicted pose.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "algo/core/image.hpp"
#include "algo/core/rigid_pose.hpp"
#include "algo/tracking/depth_smoother.hpp"
#include "algo/tracking/subject_rig.hpp"
#include "algo/tracking/tracker_geometry.hpp"

namespace fb {

struct OcclusionMask {
  // Honoured only while `on`: acquisition and calibration start from poses no mask was made for.
  bool on = false;
  std::vector<std::uint8_t> samples;         // n: hidden on this frame
  std::array<std::uint8_t, 68> landmarks{};  // a detector's points under a hand sit on the hand

  void allocate(int n) { samples.assign(static_cast<std::size_t>(n), 0); }
  bool hides_sample(int i) const { return on && samples[static_cast<std::size_t>(i)]; }
  bool hides_landmark(int l) const { return on && landmarks[static_cast<std::size_t>(l)]; }
  // Marks the samples and landmarks at pose p; turns the mask on (off with a zero margin).
  void mark(const OcclusionMaskOptions& options, const SubjectRig& rig, const TrackerCamera& camera,
            const Image<float>& image, const PixelRect& b, const RigidPoseF& p,
            const TrackLandmarks* landmarks);
};

}  // namespace fb
