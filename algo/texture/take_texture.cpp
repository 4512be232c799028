#include "algo/texture/take_texture.hpp"

#include <algorithm>
#include <string>

namespace fb {

namespace {

// `count` indices spread evenly over [0, size), the first and the last included.
std::vector<std::size_t> spread(std::size_t size, int count) {
  const auto n = static_cast<std::size_t>(std::min<std::size_t>(std::max(1, count), size));
  std::vector<std::size_t> out;
  for (std::size_t k = 0; k < n; ++k) {
    const std::size_t pick = n == 1 ? 0 : k * (size - 1) / (n - 1);
    if (out.empty() || out.back() != pick) out.push_back(pick);
  }
  return out;
}

// The detector's points on up to `count` of the views, each with the view's pose.
std::vector<FeatureView> feature_views(const TakeTextureInput& input, const TakeTexture& take,
                                       int count) {
  std::vector<FeatureView> out;
  for (const std::size_t k : spread(take.views.size(), count)) {
    const auto f = static_cast<std::size_t>(take.views[k]);
    if (auto points = input.features(f)) out.push_back({take.poses[f], *points});
  }
  return out;
}

}  // namespace

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
  for (std::size_t f = 0; f < input.frames.size(); ++f) {
    RigidPose trial = pose;
    const AlignStats s = align_to_depth(input.vertices, normals, samples, input.frames[f].depth_mm,
                                        intrinsics, trial, options.align);
    out.alignment.push_back(s);
    if (s.ok()) {
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
  std::vector<TextureView> views;
  for (const std::size_t pick : spread(good.size(), options.max_views)) {
    const int f = good[pick];
    out.views.push_back(f);
    const RgbdFrame& frame = input.frames[static_cast<std::size_t>(f)];
    views.push_back({&frame.color, &frame.depth_mm, out.poses[static_cast<std::size_t>(f)]});
  }
  TextureMesh mesh{input.vertices, normals, input.triangles};
  if (input.features && !input.feature_vertices.empty()) {
    const std::vector<FeatureView> seen = feature_views(input, out, options.feature_views);
    auto warp = estimate_feature_warp(input.vertices, normals, input.feature_vertices, seen,
                                      registration, options.warp);
    if (!warp) return warp.failure();
    out.warp = std::move(*warp);
    mesh.sample_offsets = out.warp->offsets;
  }
  auto atlas = build_texture_atlas(map, mesh, views, registration, options.texture);
  if (!atlas) return atlas.failure();
  out.atlas = std::move(*atlas);
  return out;
}

}  // namespace fb
