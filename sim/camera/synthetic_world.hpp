// The realistic synthetic world: what real Kinect recordings of real people have and the plain
// synthetic camera does not (issue 34, item 4). Every part is an option of the synthetic camera
// with its own URI key, off by default so existing figures do not move; world_presets.hpp turns
// a scenario name (`world=realistic`, or one part) into seeded values.
//
//  - Identity outside the face model's span (identity_scale, identity_extreme_modes,
//    displacement_mm, asymmetry_mm): the PCA draw scaled and its first modes pushed past
//    +-3 sigma; a smooth displacement field (a sum of seeded Gaussian bumps along the rest
//    normals, peak |d| = displacement_mm over the face) and a lateral shift of the lower face
//    (a jaw off to one side, asymmetry_mm at the chin). Applied to the rest mesh before
//    expressions, so the camera's model_vertices(), its truth landmarks and every score taken
//    against them include it.
//  - Appearance (texture, skin_tone, light_vary, hair, beard): per-subject skin tone from pale
//    to dark; a procedural per-pixel texture in rest-pose model coordinates (blotches, redness,
//    pores, brow hairs as strokes along the brow, hair strands, stubble); a key light whose
//    direction and intensity are drawn per take and drift slowly over it; colour sensor noise.
//    Hair: a cap over the top, sides and back of the head with an irregular hairline, hair
//    coloured; its depth is the hair surface (8 mm in front of the scalp), noisier and with
//    clustered dropouts (the speckle does not correlate on hair). Beard: the chin, jaw and
//    cheeks below the mouth-to-ear line, likewise with milder depth effects. The truth stays the
//    skin: what a face fit should find under the hair.
//  - Clutter (torso, desk, side_hand, hand_pass, offset_*): shoulders and chest below the head,
//    leaning so that the chest is nearer than the face at the bottom of the frame; a desk whose
//    front edge is nearer still; a forearm and hand resting beside the face, nearer than it; a
//    hand that sweeps across in front of the face over `hand_pass_frames` frames (per-frame
//    truth: FrameTruth::face_hidden_fraction); the face placed off-centre in the frame.
//  - Sensor (in KinectSensorOptions): block-correlated disparity noise and speckle dropouts.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "algo/core/camera_model.hpp"
#include "algo/core/image.hpp"
#include "algo/facemodel/face_model.hpp"
#include "algo/render/kinect_sensor.hpp"

namespace fb {

struct SyntheticWorld {
  // Subject-level randomness (bump placement, texture, hairline, light, props); kept apart
  // from SyntheticOptions::seed, which picks per-take noise, so one subject keeps its face
  // and looks over all its takes.
  std::uint64_t seed = 0;

  // Identity.
  double identity_scale = 1.0;     // id_scale=S: multiplies the identity coefficients
  int identity_extreme_modes = 0;  // id_extreme=N: first N modes pushed to >= 3.5 sigma
  double displacement_mm = 0.0;    // displace=MM: peak of the smooth displacement field
  double asymmetry_mm = 0.0;       // asym=MM: lateral shift of the chin

  // Appearance.
  bool texture = false;     // texture=on
  double skin_tone = -1.0;  // tone=T in [0, 1] (0 pale, 1 dark); < 0 = drawn from the seed
  bool light_vary = false;  // light=vary: per-take light drawn from the seed, drifting
  bool hair = false;        // hair=on
  bool beard = false;       // beard=on

  // Clutter.
  bool torso = false;        // torso=on
  bool desk = false;         // desk=on
  bool side_hand = false;    // hand=on
  bool hand_pass = false;    // hand_pass=on | START frame
  int hand_pass_start = -1;  // -1 = centred in the take
  int hand_pass_frames = 30;
  double offset_x_px = 0.0;  // offset_x=PX: face centre right of the image centre
  double offset_y_px = 0.0;  // offset_y=PX: face centre below it (negative = high)

  bool any_props() const { return torso || desk || side_hand || hand_pass; }
};

// Identity coefficients after identity_scale and identity_extreme_modes.
void adjust_identity(const SyntheticWorld& world, std::vector<float>& coefficients);

// Adds the displacement field and the asymmetry to a rest mesh (3 * vertex_count floats, the
// model's skin, identity applied). `landmarks`: the model's 68 landmark vertices.
void displace_identity(const SyntheticWorld& world, const FaceModel& model,
                       std::span<float> identity_mesh);

// Albedo of skin tone t in [0, 1] (linear 0..1 RGB), pale to dark.
Eigen::Vector3f skin_albedo(double tone);

// Per-vertex regions of the rest mesh (weights in [0, 1]).
struct WorldRegions {
  std::vector<float> hair, beard;
};
WorldRegions paint_regions(const SyntheticWorld& world, const FaceModel& model,
                           std::span<const float> identity_mesh);

// The lighting of one frame (camera frame: towards the light).
struct WorldLight {
  Eigen::Vector3f to_light = Eigen::Vector3f(-0.35f, -0.45f, -1.0f).normalized();
  float ambient = 0.3f, diffuse = 0.75f;
  Eigen::Vector3f tint = Eigen::Vector3f::Ones();
};
WorldLight world_light(const SyntheticWorld& world, std::uint64_t frame);

// Texture: modulates the interpolated albedo at rest-pose point `p` (model frame, mm).
// `hair`, `beard`, `brow` are the interpolated region weights.
Eigen::Vector3f textured_albedo(const SyntheticWorld& world, const Eigen::Vector3f& albedo,
                                const Eigen::Vector3f& p, float hair, float beard, float brow);

// Scene props (torso, desk, hands): triangles appended after the head and the wall, posed in
// the camera frame each frame.
class WorldProps {
 public:
  // `head_centre`: the face's landmark centroid in the camera frame on frame 0.
  WorldProps(const SyntheticWorld& world, int frame_count, const Eigen::Vector3f& head_centre,
             const Eigen::Vector3f& skin);

  bool empty() const { return rest_.empty(); }
  // Appends the props' vertices and triangles (once, at build time).
  void append(std::vector<Eigen::Vector3f>& vertices, std::vector<std::uint32_t>& triangles);
  // Poses the props for `frame` (the hand pass follows `head_centre`, this frame's face
  // centroid in the camera frame); absent props are put behind the camera (not drawn).
  void pose(std::uint64_t frame, const Eigen::Vector3f& head_centre,
            std::span<Eigen::Vector3f> vertices) const;
  // Albedo of scene triangle `t` (>= first_triangle()), and whether it is a hand or arm.
  Eigen::Vector3f albedo(std::uint32_t t) const;
  bool is_hand(std::uint32_t t) const;
  std::uint32_t first_triangle() const { return first_triangle_; }
  // Whether the hand pass is in front of the face region on `frame`.
  bool hand_passing(std::uint64_t frame) const;

 private:
  struct Part {
    std::uint32_t first_vertex = 0, vertex_count = 0, first_triangle = 0, triangle_count = 0;
    Eigen::Vector3f albedo = Eigen::Vector3f::Ones();
    bool hand = false, moving = false;
  };
  void add_ellipsoid(const Eigen::Vector3f& centre, const Eigen::Matrix3f& axes,
                     const Eigen::Vector3f& albedo, bool hand, bool moving);
  void add_facing(const Eigen::Vector3f& a, const Eigen::Vector3f& b, const Eigen::Vector3f& c,
                  const Eigen::Vector3f& outward);
  void add_torso(const Eigen::Vector3f& head_centre, const Eigen::Vector3f& albedo);
  void add_desk(const Eigen::Vector3f& head_centre);

  SyntheticWorld world_;
  int frame_count_ = 0;
  Eigen::Vector3f head0_;
  std::vector<Eigen::Vector3f> rest_;  // camera frame (static parts) or offsets (moving ones)
  std::vector<std::uint32_t> triangles_;
  std::vector<Part> parts_;
  std::uint32_t first_vertex_ = 0, first_triangle_ = 0;
};

// Hair and beard depth: re-measures the head pixels in those regions as the real sensor does
// (the hair surface in front of the scalp, more noise, clustered dropouts). `region_at` gives
// (hair, beard) weights at a pixel. Updates raw, depth_mm and invalid of `frame`.
struct MaterialPixel {
  float hair = 0.0f, beard = 0.0f;
};
void degrade_material_depth(const KinectSensorModel& sensor, std::span<const MaterialPixel> regions,
                            std::uint64_t noise_seed, SensorFrame& frame);

// Fraction of the face (inside the polygon of the jaw line and the brows, landmarks 0-26 in
// the depth image) whose visible surface is a hand (WorldProps::is_hand).
double face_hidden_fraction(const RasterBuffers& raster, const WorldProps& props,
                            std::span<const Eigen::Vector2d> landmarks_depth_px);

}  // namespace fb
