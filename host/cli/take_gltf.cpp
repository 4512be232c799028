#include "host/cli/take_gltf.hpp"

#include <cmath>
#include <optional>

#include "algo/tracking/arkit.hpp"
#include "host/cli/take_columns.hpp"
#include "storage/export/arkit_rig.hpp"
#include "storage/export/detail_rig.hpp"
#include "storage/export/export_session.hpp"
#include "storage/export/gltf.hpp"

namespace fb::cli {

namespace {

TakeGlb none(const std::string& why) {
  TakeGlb out;
  out.manifest = "none: " + why;
  return out;
}

// The take's frames: times from the first frame, the 52 curves in Apple's order (the ARKit
// rig's target order), the head pose in the scene frame.
GlbAnimation take_animation(const TakeData& take) {
  GlbAnimation a;
  a.name = "take_" + std::to_string(take.info.id);
  const auto column = arkit_columns(take.info.shape_names);
  for (int f = 0; f < take.info.frame_count; ++f) {
    a.times_s.push_back(
        static_cast<float>(take.times_s[static_cast<std::size_t>(f)] - take.times_s.front()));
    const auto curves = arkit_curves(take, column, f);
    a.weights.insert(a.weights.end(), curves.begin(), curves.end());
    append_head_pose(take_pose(take, f), a);
  }
  return a;
}

// Shape k's own detail: H_k = sum_e c_e(k) (D_e - N), c(k) = P^T to_model(ARKit curve k at 1)
// (to_model is linear: each model shape takes the value of the one curve it feeds). Empty
// where the shape moves no map.
Result<std::vector<FloatImage>> arkit_shape_detail(const SessionDetailBlend& d,
                                                   const FaceModel& model) {
  auto mapping = make_arkit_mapping(model);
  if (!mapping) return mapping.failure();
  const auto& neutral = d.maps.front().displacement_mm;
  std::vector<FloatImage> out(kArkitShapeCount);
  std::vector<float> a(static_cast<std::size_t>(model.fitting_expression_count));
  std::vector<float> c(d.captures.size());
  for (int k = 0; k < kArkitShapeCount; ++k) {
    std::array<float, kArkitShapeCount> unit{};
    unit[k] = 1.0f;
    std::fill(a.begin(), a.end(), 0.0f);
    mapping->to_model(unit, a);
    d.blend.map_weights(a, c);
    FloatImage& h = out[static_cast<std::size_t>(k)];
    for (std::size_t e = 0; e < c.size(); ++e) {
      if (c[e] == 0.0f) continue;
      if (h.width == 0) h.resize(d.maps.front().width, d.maps.front().height);
      const auto& layer = d.maps[e + 1].displacement_mm;
      for (std::size_t i = 0; i < h.pixels.size(); ++i)
        h.pixels[i] += c[e] * (layer[i] - neutral[i]);
    }
  }
  return out;
}

// The rig with the detail as geometry (detail_rig.hpp); `uvs` becomes the subdivided layout.
Result<DetailRig> detailed_rig(const RigData& arkit, const MeshUvs& uvs,
                               const SessionDetailBlend& d, const FaceModel& model) {
  auto shapes = arkit_shape_detail(d, model);
  if (!shapes) return shapes.failure();
  FloatImage neutral;
  neutral.resize(d.maps.front().width, d.maps.front().height);
  neutral.pixels = d.maps.front().displacement_mm;
  return make_detail_rig({&arkit, &uvs, &neutral, &*shapes});
}

GlbAnimationExtra map_weight_extra(const TakeGlbInput& in) {
  GlbAnimationExtra e;
  e.key = "detail_weights";
  e.description = detail_weights_description() +
                  ". One row per frame of this animation's input (the take's frames); the maps "
                  "are wrinkles/capture_I_normal.png and _displacement.pgm beside this file; "
                  "the mesh's morph targets already carry the same detail as geometry";
  e.columns = detail_weight_columns(*in.detail);
  return e;
}

}  // namespace

Result<TakeGlb> write_take_glb(const TakeGlbInput& in, ExportFolder& folder) {
  const TakeData& take = *in.take;
  if (!take.info.session)
    return none(
        "the take records no session, so there is no rig to animate (a take tracked with "
        "--store S --session N records its session)");
  const SessionId session = *take.info.session;
  if (in.model == nullptr) return none(in.model_problem);
  auto serving = in.store->rig_for(session);
  if (!serving) return serving.failure();
  if (!*serving)
    return none("session " + std::to_string(session) +
                "'s subject has no rig to animate (build one: facebooth rig --store " +
                in.store->root().string() + " --session " + std::to_string(session) + " --save)");
  // The rig, texture and detail export --session writes; the capture frames are not needed.
  auto content = load_session_content(*in.store, session, {.capture_frames = false});
  if (!content) return content.failure();
  use_face_model_uvs(*content, *in.model);
  auto arkit = to_arkit_rig(content->rig);
  if (!arkit) return none(arkit.error().message);
  GlbAnimation animation = take_animation(take);
  if (auto usable = check_animation(animation, kArkitShapeCount); !usable)
    return none("the take cannot be animated: " + usable.error().message);
  TakeGlb out;
  out.file = "take_" + std::to_string(take.info.id) + ".glb";
  GlbOptions options;
  options.name = content->name;
  options.base_color_png = &content->texture_png;
  options.animation = &animation;
  const RigData* rig = &arkit->rig;
  options.uvs = &content->uvs;
  options.normal_png = neutral_normal_png(*content);  // without the blend: the neutral's map
  std::optional<DetailRig> detail;
  if (in.detail != nullptr && content->uvs.fits(arkit->rig.triangles)) {
    auto made = detailed_rig(arkit->rig, content->uvs, *in.detail, *in.model);
    if (!made) return made.failure();
    detail = std::move(*made);
    rig = &detail->rig;
    options.uvs = &detail->uvs;
    options.normal_png = nullptr;  // the geometry carries the detail: the map would double it
    auto c = take_map_weights(take, *in.detail, *in.model);
    if (!c) return c.failure();
    animation.extras.push_back(map_weight_extra(in));
    animation.extras.back().values = std::move(*c);
    out.detail = true;
  }
  auto glb = encode_glb(*rig, options);
  if (!glb) return glb.failure();
  if (auto r = folder.write_file(out.file, *glb); !r) return r.failure();
  out.vertices =
      options.uvs->fits(rig->triangles)
          ? static_cast<int>(split_seams(rig->triangles, *options.uvs).source_vertex.size())
          : rig->vertex_count();
  out.manifest = out.file + ": session " + std::to_string(session) + "'s rig (" +
                 content->source["rig"] +
                 ") as export --session --format glb writes it (52 ARKit " +
                 "morph targets, metres), animated by glTF animation '" + animation.name +
                 "': LINEAR samplers at the take's measured frame times; weights on node 1 (the "
                 "mesh), the head pose on node 0 'head' (scene = the depth camera's frame turned "
                 "180 degrees about X: +Y up, +Z toward the camera, origin at the camera)";
  if (out.detail)
    out.manifest += "; wrinkle detail as geometry: the mesh subdivided under the detail (" +
                    std::to_string(out.vertices) + " glTF vertices from " +
                    std::to_string(detail->source_vertices) +
                    "), the neutral's displacement in the base positions and each target's own "
                    "detail (H_k = sum_e c_e(k) (D_e - N)) along the neutral's normals; the "
                    "per-frame map weights in animations[0].extras.detail_weights";
  return out;
}

}  // namespace fb::cli
