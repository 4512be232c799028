// Internal to the synthetic camera (synthetic_camera.cpp renders, synthetic_camera_build.cpp
// builds): the render state behind SyntheticCamera and the seeded draws both use.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <numbers>
#include <optional>
#include <span>
#include <vector>

#include "sim/camera/hashed_draws.hpp"
#include "sim/camera/render_ahead.hpp"
#include "sim/camera/synthetic_camera.hpp"
#include "sim/camera/synthetic_world.hpp"

namespace fb {
namespace synthetic_detail {

inline constexpr std::uint64_t kStreamIdentity = 1, kStreamSkin = 2;

enum class CapKind { kEye, kMouth, kFlat };

struct Cap {
  std::vector<std::uint32_t> loop;  // boundary vertices in order (edges loop[i] -> loop[i+1])
  CapKind kind = CapKind::kFlat;
};

}  // namespace synthetic_detail

struct SyntheticCamera::State {
  State(const KinectRegistration& registration, const SyntheticOptions& o)
      : options(o), sensor(registration, o.sensor) {}

  CameraInfo info;
  SyntheticOptions options;
  KinectSensorModel sensor;
  // A decalibrated unit's depth in millimetres as its driver reports it: the raw disparity
  // through the reported (default) disparity law, not the unit's true one.
  std::optional<KinectRegistration> reported_registration;

  int skin_vertex_count = 0;
  int mesh_vertex_count = 0;            // skin + cap apexes
  std::vector<float> identity_mesh;     // 3 * skin_vertex_count, identity applied
  std::vector<float> expression_basis;  // copied only for expression tracks
  int expression_count = 0;
  std::vector<float> current_weights;
  std::vector<float> evaluated;  // 3 * skin_vertex_count scratch
  std::vector<synthetic_detail::Cap> caps;
  std::vector<std::uint32_t> triangles;   // skin, caps, wall
  std::uint32_t mesh_triangle_count = 0;  // skin + caps (ids below this are the head)
  std::array<std::uint32_t, 68> landmarks{};
  Eigen::Vector3d rest_centroid = Eigen::Vector3d::Zero();

  std::vector<Eigen::Vector3f> model_vertices;  // mesh_vertex_count, current expression
  std::vector<Eigen::Vector3f> model_normals;
  std::vector<Eigen::Vector3f> albedo;
  std::vector<Eigen::Vector3f> scene_vertices;  // camera frame, + wall corners

  // The realistic world (synthetic_world.hpp): props, hair/beard regions, texture inputs.
  std::optional<WorldProps> props;
  WorldRegions regions;
  std::vector<float> brow_weight;       // per mesh vertex, for the brow texture
  std::vector<MaterialPixel> material;  // per depth pixel, hair/beard weights
  Eigen::Vector3f skin = Eigen::Vector3f::Zero();

  SensorFrame sensor_frame;
  FrameTruth truth;                   // of the frame last delivered
  std::vector<float> identity_truth;  // the subject's identity coefficients (sigma units)
  Image<float> color_z;
  Image<std::uint8_t> color_mark;
  ColorImage color;

  bool started = false;
  std::uint64_t next_index = 0;
  // realtime=1: renders ahead on its own thread (declared last: stopped before the rest goes).
  std::unique_ptr<RenderAhead> ahead;

  // Renders frame `index` from the current options into `frame` and `truth`.
  Result<void> render(std::uint64_t index, RgbdFrame& frame, FrameTruth& truth,
                      bool with_noiseless_depth, bool with_depth_mm);
  void depth_from_raw(RgbdFrame& frame) const;
  void finish_realtime();
  void set_expression(std::span<const float> basis, std::span<const float> weights);
  RigidPose pose_at(std::uint64_t index) const;
  void shade_color(std::uint64_t frame_index, const RigidPose& camera_from_model);
  void world_depth(std::uint64_t noise_seed);
  Eigen::Vector3f head_albedo(std::int32_t t, float b1, float b2) const;
  Eigen::Vector2d color_position(const Eigen::Vector2d& px, double z) const;
};

}  // namespace fb
