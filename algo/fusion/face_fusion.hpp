// The face-box KinectFusion pipeline (FaceWarehouse section 3.1): owns the objects (TSDF volume,
// depth pyramid, ray-cast model view) and drives the engines (preprocess, ICP tracker,
// integrator, ray caster) frame by frame. Everything is allocated in reset(); process() does not
// allocate. Pure algorithm: depth images in, poses, views and meshes out.
//
//   FaceFusion fusion;
//   if (auto ok = fusion.reset(intrinsics, box, options); !ok) ...;
//   for (each frame) { FrameReport r = fusion.process(frame.depth_mm); ... }
//   SurfaceView frontal = fusion.render(first_pose);   // smooth depth + normals
//   TriangleMesh mesh = fusion.extract_mesh();
#pragma once

#include <memory>
#include <vector>

#include "algo/core/camera_model.hpp"
#include "algo/core/image.hpp"
#include "algo/core/result.hpp"
#include "algo/fusion/fusion_maps.hpp"
#include "algo/fusion/fusion_types.hpp"
#include "algo/fusion/icp_tracker.hpp"
#include "algo/fusion/integrator.hpp"
#include "algo/fusion/marching_cubes.hpp"
#include "algo/fusion/parallel.hpp"
#include "algo/fusion/preprocess.hpp"
#include "algo/fusion/ray_caster.hpp"
#include "algo/fusion/tsdf_volume.hpp"

namespace fb {

class FaceFusion {
 public:
  FaceFusion();
  ~FaceFusion();
  FaceFusion(const FaceFusion&) = delete;
  FaceFusion& operator=(const FaceFusion&) = delete;

  // Validates the options and the box, allocates every buffer, and forgets previous frames.
  Result<void> reset(const PinholeIntrinsics& intrinsics, const FaceBox& face_box,
                     const FusionOptions& options = {});

  // Tracks and fuses one depth frame (mm, 0 = invalid). Never throws or crashes on bad input:
  // an empty or wrongly sized frame is reported as kBadInput, a frame that cannot be tracked as
  // kLost (and is not fused). While lost, every frame re-tries from the last good pose.
  //
  // With `known_pose` (world_from_camera; the world being the first fused frame's camera when
  // that frame's pose is the identity), the frame is fused at that pose without ICP: for
  // ground-truth studies, or when another tracker supplies the poses.
  FrameReport process(const DepthImage& depth_mm, const RigidPose* known_pose = nullptr);

  bool started() const { return started_; }
  bool lost() const { return lost_; }
  RigidPose last_good_pose() const { return last_good_.to_rigid(); }
  const FaceBox& face_box() const { return box_; }  // this frame's (it follows the face)
  // The face box for a camera pose: reset()'s box moved and scaled with the face when
  // box_follows_face (the box a frame at that pose is fused over), else reset()'s box.
  FaceBox box_for(const RigidPose& world_from_camera) const {
    return box_at(RigidPoseF::from(world_from_camera));
  }
  const FusionOptions& options() const { return options_; }
  const TsdfVolume& volume() const { return volume_; }
  const ModelView& model_view() const { return model_; }

  // Ray-casts depth and normals of the fused surface over the face box from a camera pose
  // (e.g. the frontal frame's). `out` is resized on first use and reused afterwards.
  void render(const RigidPose& world_from_camera, SurfaceView& out);
  SurfaceView render(const RigidPose& world_from_camera);

  TriangleMesh extract_mesh(const MeshOptions& options = {}) const;

 private:
  void place_volume(const RigidPoseF& world_from_camera);
  void cast_model(const RigidPoseF& pose);
  FaceBox box_at(const RigidPoseF& world_from_camera) const;
  void set_chin_cut(const RigidPoseF& world_from_camera);

  FusionOptions options_;
  PinholeIntrinsics intrinsics_;
  FaceBox box_;        // the current frame's
  FaceBox start_box_;  // reset()'s, clipped
  // The point the box follows: the face at the start box's centre (world frame), and its depth
  // in the first frame (0 until fusion starts).
  Eigen::Vector3f anchor_world_ = Eigen::Vector3f::Zero();
  float anchor_depth_ = 0.0f;
  // The cut below the chin (FaceBox::chin_mm / down) in the world frame; down = 0: none.
  Eigen::Vector3f chin_world_ = Eigen::Vector3f::Zero();
  Eigen::Vector3f down_world_ = Eigen::Vector3f::Zero();
  std::unique_ptr<ParallelRunner> runner_;
  DepthPreprocessor preprocessor_;
  IcpTracker tracker_;
  TsdfIntegrator integrator_;
  RayCaster ray_caster_;
  TsdfVolume volume_;
  DepthPyramid pyramid_;
  ModelView model_;
  MapLevel render_level_;              // scratch for render()
  std::vector<float> scratch_depths_;  // for placing the volume
  RigidPoseF last_good_;
  bool configured_ = false;
  bool started_ = false;
  bool lost_ = false;
};

}  // namespace fb
