#include "host/cli/session_texture.hpp"

#include <chrono>
#include <map>

#include <nlohmann/json.hpp>

#include "algo/core/clock.hpp"
#include "drivers/camera/common/device_json.hpp"
#include "storage/asset_files.hpp"
#include "storage/export/png_file.hpp"

namespace fb::cli {

Result<KinectCalibration> session_calibration(const SessionInfo& session, std::string& note) {
  if (session.calibration_json.empty()) {
    note = "session " + std::to_string(session.id) +
           " recorded no unit calibration (a store from before schema v4): assuming the "
           "default Kinect calibration";
    return KinectCalibration::defaults();
  }
  auto c = parse_device_json(session.calibration_json);
  if (!c)
    return fail("session " + std::to_string(session.id) +
                "'s recorded calibration is unreadable (" + c.error().message + ")");
  return *c;
}

// The newest fitted mesh of each capture (a neutral mesh counts for its capture).
Result<std::map<int, MeshId>> fitted_meshes(const SessionStore& store, SessionId session) {
  auto meshes = store.meshes(session);
  if (!meshes) return meshes.failure();
  std::map<int, MeshId> out;
  for (const auto& m : *meshes) {
    if (m.role == MeshRole::kScan) continue;
    const int index = m.capture_index.value_or(m.role == MeshRole::kNeutral ? 0 : -1);
    if (index >= 0) out[index] = m.id;  // listed oldest first: the newest wins
  }
  return out;
}

Result<SessionAtlasInputs> session_atlas_inputs(const SessionStore& store, const SessionInfo& info,
                                                const FaceModel& model, int size) {
  SessionAtlasInputs in;
  auto calibration = session_calibration(info, in.note);
  if (!calibration) return calibration.failure();
  in.calibration = *calibration;
  in.uvs = model.atlas_uvs();
  auto map = make_texel_map(in.uvs, model.triangle_uvs, size * model.uv_tiles(), size);
  if (!map) return map.failure();
  in.map = std::move(*map);
  auto meshes = fitted_meshes(store, info.id);
  if (!meshes) return meshes.failure();
  if (meshes->find(0) == meshes->end())
    return fail("session " + std::to_string(info.id) +
                " has no fitted neutral (capture 0); finish or refit the session first");
  in.meshes = std::move(*meshes);
  auto captures = store.captures(info.id);
  if (!captures) return captures.failure();
  in.captures = std::move(*captures);
  return in;
}

Result<TakeTexture> texture_capture(const SessionStore& store, SessionId session, int capture_index,
                                    const FaceModel& model, const TexelMap& map,
                                    const KinectRegistration& registration,
                                    const TakeTextureOptions& options) {
  auto meshes = fitted_meshes(store, session);
  if (!meshes) return meshes.failure();
  const auto found = meshes->find(capture_index);
  if (found == meshes->end())
    return fail("capture " + std::to_string(capture_index) + " of session " +
                std::to_string(session) + " has no fitted mesh; fit it first");
  auto mesh = store.read_mesh(found->second);
  if (!mesh) return mesh.failure();
  if (mesh->vertex_count() != model.vertex_count)
    return fail("the fitted mesh does not have the face model's topology, so it has no UV layout");
  auto capture = store.read_capture(session, capture_index);
  if (!capture) return capture.failure();
  // The stored points are dlib's: they mark the embedding's vertices, as in the fit.
  auto embedding = landmark_embedding_beside(model, default_face_model_path());
  if (!embedding) return embedding.failure();
  const LandmarkEmbedding marks = embedding->value_or(model_landmark_embedding(model));
  std::vector<Eigen::Vector3d> model_points, camera_points;
  for (std::size_t l = 0; l < capture->landmarks.size() && l < model.landmark_vertices.size();
       ++l) {
    const Landmark& p = capture->landmarks[l];
    if (l < 17 || !p.has_3d) continue;  // interior points carry reliable 3D
    const auto v = marks.for_expression(capture->info.expression)[l];
    model_points.emplace_back(mesh->positions[3 * v], mesh->positions[3 * v + 1],
                              mesh->positions[3 * v + 2]);
    camera_points.emplace_back(p.x, p.y, p.z);
  }
  TakeTextureInput in;
  in.vertices = mesh->positions;
  in.triangles = model.triangles;
  in.region_vertices = model.face_vertex_count;
  in.frames = capture->frames;
  in.landmarks_model = model_points;
  in.landmarks_camera = camera_points;
  return texture_from_take(map, in, registration, options);
}

Result<std::vector<CaptureTextureReport>> texture_session(
    SessionStore& store, SessionId session, const FaceModel& model, int size, bool expressions,
    bool save, const std::function<void(int, int)>& progress) {
  if (model.uvs.empty())
    return fail(
        "the face model asset has no UV layout; reconvert it with facebooth-convert-facemodel");
  auto info = store.session(session);
  if (!info) return info.failure();
  auto inputs = session_atlas_inputs(store, *info, model, size);
  if (!inputs) return inputs.failure();
  const std::string& note = inputs->note;
  const KinectRegistration registration(inputs->calibration);
  const TexelMap* map = &inputs->map;
  const std::map<int, MeshId>* meshes = &inputs->meshes;
  const std::vector<CaptureInfo>* captures = &inputs->captures;
  std::vector<int> todo;
  for (const auto& [index, id] : *meshes)
    if (index == 0 || expressions) todo.push_back(index);
  std::vector<CaptureTextureReport> out;
  for (const int index : todo) {
    const auto t0 = Clock::now();
    auto t = texture_capture(store, session, index, model, *map, registration);
    if (!t) return fail("capture " + std::to_string(index) + ": " + t.error().message);
    CaptureTextureReport r;
    r.capture_index = index;
    for (const auto& c : *captures)
      if (c.index == index) r.expression = c.expression;
    r.frames = static_cast<int>(t->poses.size());
    r.frames_aligned = t->frames_aligned;
    r.views = static_cast<int>(t->views.size());
    r.observed_fraction = static_cast<double>(t->atlas.report.observed_texels) /
                          std::max(1, t->atlas.report.covered_texels);
    if (save) {
      auto png = encode_png(t->atlas.image);
      if (!png) return png.failure();
      nlohmann::json params = {{"views", t->views},
                               {"frames_aligned", t->frames_aligned},
                               {"observed_fraction", r.observed_fraction},
                               {"calibration", note.empty() ? "recorded" : "defaults"}};
      auto id = store.add_texture(session, index == 0 ? std::nullopt : std::optional<int>(index),
                                  map->width, map->height, *png, params.dump());
      if (!id) return id.failure();
      r.stored = *id;
    }
    r.seconds = ms_since(t0) / 1000.0;
    out.push_back(r);
    if (progress) progress(static_cast<int>(out.size()), static_cast<int>(todo.size()));
  }
  return out;
}

}  // namespace fb::cli
