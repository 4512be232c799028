#include "algo/texture/take_texture.hpp"

#include <algorithm>
#include <string>

namespace fb {

Result<TakeTexture> texture_from_take(const TexelMap& map, const TakeTextureInput& input,
                                      const KinectRegistration& registration,
                                      const TakeTextureOptions& options) {
  if (input.frames.empty()) return fail("the take has no frames");
  if (input.vertices.empty() || input.triangles.empty()) return fail("no mesh to texture");
  RigidPose pose;
  if (input.start) {
    pose = *input.start;
  } else {
    auto p = rigid_from_pairs(input.landmarks_model, input.landmarks_camera);
    if (!p) return p.failure();
    pose = *p;
  }
  const std::vector<float> normals = vertex_normals(input.vertices, input.triangles);
  const int region = input.region_vertices > 0 ? input.region_vertices
                                               : static_cast<int>(input.vertices.size() / 3);
  const std::vector<std::uint32_t> samples = alignment_samples(region, options.align.max_samples);
  const PinholeIntrinsics intrinsics = registration.depth_intrinsics();
  TakeTexture out;
  std::vector<int> good;
  AlignOptions tracking = options.align;
  tracking.iterations = options.align.tracking_iterations;
  tracking.first_gate_mm = options.align.tracking_first_gate_mm;
  RigidPose previous = pose;  // the pose one aligned frame before `pose`
  bool moving = false;
  for (std::size_t f = 0; f < input.frames.size(); ++f) {
    RigidPose trial = pose;
    if (moving) {
      // Constant velocity: the last frame-to-frame motion applied once more.
      const Eigen::Quaterniond dr = pose.rotation * previous.rotation.conjugate();
      trial.rotation = (dr * pose.rotation).normalized();
      trial.translation = dr * (pose.translation - previous.translation) + pose.translation;
    }
    const AlignStats s = align_to_depth(input.vertices, normals, samples, input.frames[f].depth_mm,
                                        intrinsics, trial, good.empty() ? options.align : tracking);
    out.alignment.push_back(s);
    if (s.ok()) {
      moving = !good.empty() && good.back() + 1 == static_cast<int>(f);
      previous = pose;
      pose = trial;
      ++out.frames_aligned;
      good.push_back(static_cast<int>(f));
    }
    out.poses.push_back(pose);
  }
  if (good.empty())
    return fail("the mesh could not be aligned with any frame's depth (" +
                std::to_string(out.alignment.front().inliers) + " of " +
                std::to_string(out.alignment.front().samples) +
                " points on frame 0); check that the mesh belongs to this take");
  // Views spread evenly over the aligned frames, the first and the last included.
  const int n = std::min<int>(std::max(1, options.max_views), static_cast<int>(good.size()));
  std::vector<TextureView> views;
  for (int k = 0; k < n; ++k) {
    const std::size_t pick =
        n == 1 ? 0
               : static_cast<std::size_t>(k) * (good.size() - 1) / static_cast<std::size_t>(n - 1);
    const int f = good[pick];
    if (!out.views.empty() && out.views.back() == f) continue;
    out.views.push_back(f);
    const RgbdFrame& frame = input.frames[static_cast<std::size_t>(f)];
    views.push_back({&frame.color, &frame.depth_mm, out.poses[static_cast<std::size_t>(f)]});
  }
  TextureMesh mesh{input.vertices, normals, input.triangles};
  auto atlas = build_texture_atlas(map, mesh, views, registration, options.texture);
  if (!atlas) return atlas.failure();
  out.atlas = std::move(*atlas);
  return out;
}

}  // namespace fb
