// The laboratory's ground truth of a rendered frame, and how the lab asks a camera for it.
// Product code never sees it: DepthCamera has no truth; the synthetic camera (and the board
// scene) also implement GroundTruthCamera, and frame_truth() finds it by dynamic_cast, through
// a CalibratedCamera wrapper too.
#pragma once

#include <vector>

#include <Eigen/Core>

#include "algo/core/camera_model.hpp"
#include "algo/core/image.hpp"
#include "drivers/camera/depth_camera.hpp"

namespace fb {

// Per-frame ground truth, filled by the synthetic backend.
struct FrameTruth {
  RigidPose camera_from_model;                      // model frame (mm) -> depth camera frame (mm)
  std::vector<float> identity_coeffs;               // model identity coefficients (sigma units)
  std::vector<float> expression_weights;            // one per model expression shape
  std::vector<Eigen::Vector3d> landmarks_3d;        // 68 iBUG points, depth camera frame, mm
  std::vector<Eigen::Vector2d> landmarks_depth_px;  // 68 points projected into the depth image
  std::vector<Eigen::Vector2d> landmarks_color_px;  // 68 points in the colour image
  Image<float> noiseless_depth_mm;  // rendered depth before the sensor model, 0 = background/none
  // Fraction of the face (jaw line and brows polygon) hidden by a hand in front of it.
  double face_hidden_fraction = 0.0;
};

// What a rendering camera offers besides DepthCamera.
class GroundTruthCamera {
 public:
  virtual ~GroundTruthCamera() = default;
  // Ground truth of the frame last returned, or nullptr when there is none.
  virtual const FrameTruth* truth() const = 0;
};

// The truth of `camera`'s last frame (looking through a CalibratedCamera), or nullptr when the
// camera renders none (a real device, a replay).
const FrameTruth* frame_truth(const DepthCamera& camera);

}  // namespace fb
