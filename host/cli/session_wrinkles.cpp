#include "host/cli/session_wrinkles.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>

#include <nlohmann/json.hpp>

#include "algo/core/clock.hpp"
#include "algo/texture/mesh_alignment.hpp"
#include "host/cli/session_texture.hpp"
#include "storage/export/png_file.hpp"

namespace fb::cli {

namespace {

// Where the fitted mesh is in the depth camera: its landmark vertices against the capture's
// interior 3D landmarks (the contour's 0-16 have no reliable 3D).
Result<RigidPose> mesh_pose(const MeshData& mesh, const CaptureData& capture,
                            const FaceModel& model) {
  std::vector<Eigen::Vector3d> model_points, camera_points;
  for (std::size_t l = 17; l < capture.landmarks.size() && l < model.landmark_vertices.size();
       ++l) {
    const Landmark& p = capture.landmarks[l];
    if (!p.has_3d) continue;
    const auto v = model.landmark_vertices[l];
    model_points.emplace_back(mesh.positions[3 * v], mesh.positions[3 * v + 1],
                              mesh.positions[3 * v + 2]);
    camera_points.emplace_back(p.x, p.y, p.z);
  }
  if (model_points.size() < 6)
    return fail("it has " + std::to_string(model_points.size()) +
                " landmarks with depth (6 or more are needed to place the fitted mesh); "
                "correct its landmarks or recapture it");
  return rigid_from_pairs(model_points, camera_points);
}

}  // namespace

Result<std::vector<CaptureWrinkleReport>> wrinkle_session(
    SessionStore& store, SessionId session, const FaceModel& model,
    const WrinkleSessionOptions& options, const std::function<void(int, int)>& progress) {
  if (model.uvs.empty())
    return fail(
        "the face model asset has no UV layout; reconvert it with facebooth-convert-facemodel");
  if (options.exemplars.empty()) return fail("no wrinkle exemplars were loaded");
  auto info = store.session(session);
  if (!info) return info.failure();
  auto rig = store.rig_for(session);
  if (!rig) return rig.failure();
  if (!*rig)
    return fail("session " + std::to_string(session) +
                "'s subject has no rig to add wrinkle detail to; build one first: facebooth rig "
                "--store DIR --session " +
                std::to_string(session));
  auto inputs = session_atlas_inputs(store, *info, model, options.size);
  if (!inputs) return inputs.failure();
  const std::string& note = inputs->note;
  const KinectRegistration registration(inputs->calibration);
  const TexelMap* map = &inputs->map;
  const std::map<int, MeshId>* meshes = &inputs->meshes;
  const std::vector<float>& uvs = inputs->uvs;
  const std::vector<CaptureInfo>* captures = &inputs->captures;
  CaptureDetailOptions detail_options;
  detail_options.detail.exemplar_mm_per_px = options.exemplar_mm_per_px;
  std::vector<CaptureWrinkleReport> out;
  // The neutral (capture 0, first) is synthesised from its own frame; every other capture from
  // its ratio to the neutral (WrinkleDetailOptions::ratio_image).
  std::optional<CaptureDetail> neutral;
  for (const auto& [index, mesh_id] : *meshes) {
    const auto t0 = Clock::now();
    const std::string where =
        "capture " + std::to_string(index) + " of session " + std::to_string(session);
    auto mesh = store.read_mesh(mesh_id);
    if (!mesh) return mesh.failure();
    if (mesh->vertex_count() != model.vertex_count)
      return fail(where +
                  ": the fitted mesh does not have the face model's topology, so it has "
                  "no UV layout to carry detail");
    CaptureReadOptions read;
    read.max_frames = 1;
    auto capture = store.read_capture(session, index, read);
    if (!capture) return fail(where + ": " + capture.error().message);
    if (capture->frames.empty() || capture->frames.front().color.pixels.empty())
      return fail(where + " has no colour frame to find wrinkles in; recapture it");
    auto pose = mesh_pose(*mesh, *capture, model);
    if (!pose) return fail(where + ": " + pose.error().message);
    CaptureDetailInput in;
    in.color = &capture->frames.front().color;
    in.vertices = mesh->positions;
    in.triangles = model.triangles;
    in.depth_from_model = *pose;
    in.landmark_vertices = model.landmark_vertices;
    in.map = &*map;
    in.uvs = uvs;
    in.triangle_uvs = model.triangle_uvs;
    if (index != 0 && neutral) in.neutral = &*neutral;
    CaptureDetailOptions capture_options = detail_options;
    capture_options.detail.given_alongside = options.also_detect;
    capture_options.detail.regions.wrinkle_zones = options.zones;
    capture_options.detail.local_light = options.local_light;
    const ColorImage& color = capture->frames.front().color;
    for (const auto& g : options.regions) {
      if (g.capture && *g.capture != index) continue;
      const PixelRect& r = g.rect;
      if (r.x0 < 0 || r.y0 < 0 || r.width() <= 0 || r.height() <= 0 || r.x1 > color.width ||
          r.y1 > color.height)
        return fail(where + ": the region " + std::to_string(r.x0) + "," + std::to_string(r.y0) +
                    "," + std::to_string(r.width()) + "," + std::to_string(r.height()) +
                    " is not inside its colour frame (" + std::to_string(color.width) + " x " +
                    std::to_string(color.height) + " pixels)");
      capture_options.color_regions.push_back(r);
    }
    auto detail = capture_detail(in, registration, options.exemplars, capture_options);
    if (!detail) return fail(where + ": " + detail.error().message);
    CaptureWrinkleReport r;
    r.capture_index = index;
    for (const auto& c : *captures)
      if (c.index == index) r.expression = c.expression;
    r.regions = static_cast<int>(detail->detail.regions.regions.size());
    r.given_regions = static_cast<int>(capture_options.color_regions.size());
    r.texels_with_detail = detail->maps.texels_with_detail;
    r.ratio_to_neutral = in.neutral != nullptr;
    for (const float h : detail->maps.displacement_mm.pixels)
      r.max_height_mm = std::max(r.max_height_mm, static_cast<double>(std::abs(h)));
    if (options.save) {
      WrinkleDetailData data;
      data.width = map->width;
      data.height = map->height;
      data.displacement_mm = detail->maps.displacement_mm.pixels;
      auto png = encode_png(detail->maps.normal_map);
      if (!png) return png.failure();
      data.normal_png = std::move(*png);
      const nlohmann::json params = {{"regions", r.regions},
                                     {"given_regions", r.given_regions},
                                     {"texels_with_detail", r.texels_with_detail},
                                     {"mm_per_px", detail->detail.image_mm_per_px},
                                     {"mesh_id", mesh_id},
                                     {"ratio_to_neutral", r.ratio_to_neutral},
                                     {"calibration", note.empty() ? "recorded" : "defaults"}};
      auto id = store.add_wrinkle_detail(session, index, (*rig)->id, data, params.dump());
      if (!id) return id.failure();
      r.stored = *id;
    }
    if (index == 0) neutral = std::move(*detail);
    r.seconds = ms_since(t0) / 1000.0;
    out.push_back(r);
    if (progress) progress(static_cast<int>(out.size()), static_cast<int>(meshes->size()));
  }
  return out;
}

}  // namespace fb::cli
