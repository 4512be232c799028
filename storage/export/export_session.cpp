#include "storage/export/export_session.hpp"

#include <cctype>
#include <chrono>
#include <cstdio>

#include "storage/export/export_folder.hpp"
#include "storage/export/facewarehouse.hpp"
#include "storage/export/gltf.hpp"
#include "storage/export/mesh_files.hpp"

namespace fb {

Result<ExportFormat> parse_export_format(std::string_view name) {
  if (name == "facewarehouse" || name == "fw") return ExportFormat::kFaceWarehouse;
  if (name == "glb" || name == "gltf") return ExportFormat::kGlb;
  if (name == "obj") return ExportFormat::kObj;
  if (name == "ply") return ExportFormat::kPly;
  return fail("unknown export format '" + std::string(name) +
              "': use facewarehouse, glb, obj or ply");
}

const char* to_string(ExportFormat format) {
  switch (format) {
    case ExportFormat::kFaceWarehouse:
      return "facewarehouse";
    case ExportFormat::kGlb:
      return "glb";
    case ExportFormat::kObj:
      return "obj";
    case ExportFormat::kPly:
      return "ply";
  }
  return "facewarehouse";
}

Result<ExportContent> load_session_content(const SessionStore& store, SessionId session) {
  auto info = store.session(session);
  if (!info) return info.failure();
  ExportContent content;
  content.name = "subject" + std::to_string(info->subject);
  content.source = {{"kind", "session"},
                    {"store", store.root().string()},
                    {"session", std::to_string(session)},
                    {"subject", std::to_string(info->subject)}};
  auto meshes = store.meshes(session);
  if (!meshes) return meshes.failure();
  auto serving = store.rig_for(session);
  if (!serving) return serving.failure();
  if (!*serving) {
    // A session with only its neutral fitted cannot be rigged (rigging needs an expression),
    // but its neutral is a result of its own: exported as a rig without blendshapes.
    const MeshInfo* neutral = nullptr;
    for (const auto& m : *meshes)
      if (m.role == MeshRole::kNeutral && (neutral == nullptr || m.id > neutral->id)) neutral = &m;
    if (neutral == nullptr) {
      return fail("subject " + std::to_string(info->subject) + " of session " +
                  std::to_string(session) +
                  " has no rig yet and no fitted neutral: fit the session's neutral capture (and "
                  "build a rig from its expressions) first, or try --from-face-model");
    }
    auto mesh = store.read_mesh(neutral->id);
    if (!mesh) return mesh.failure();
    content.rig.neutral = std::move(mesh->positions);
    content.rig.triangles = std::move(mesh->triangles);
    content.source["rig"] =
        "none: the fitted neutral alone (mesh " + std::to_string(neutral->id) + "), no blendshapes";
  } else {
    const RigId chosen = (*serving)->id;
    content.source["rig"] = std::to_string(chosen);
    auto rig = store.read_rig(chosen);
    if (!rig) return rig.failure();
    content.rig = std::move(*rig);
  }

  auto captures = store.captures(session);
  if (!captures) return captures.failure();
  for (const auto& c : *captures) {
    // The newest fitted (or neutral) mesh of this capture.
    const MeshInfo* found = nullptr;
    for (const auto& m : *meshes) {
      if (m.capture_index == c.index && m.role != MeshRole::kScan) found = &m;
    }
    if (found == nullptr) continue;
    auto mesh = store.read_mesh(found->id);
    if (!mesh) return mesh.failure();
    content.poses.push_back(std::move(*mesh));
    content.pose_names.push_back(c.expression);
    ColorImage color;
    std::vector<Landmark> landmarks;
    if (c.state == CaptureState::kDone) {
      auto data = store.read_capture(session, c.index, {.max_frames = 1});  // colour of frame 0
      if (!data) return data.failure();
      if (!data->frames.empty()) color = std::move(data->frames.front().color);
      landmarks = std::move(data->landmarks);
    }
    content.pose_colors.push_back(std::move(color));
    content.pose_landmarks.push_back(std::move(landmarks));
  }
  return content;
}

ExportContent synthetic_content(const SyntheticSubject& subject, std::uint64_t seed,
                                const std::string& face_model_path) {
  ExportContent content;
  content.name = "synthetic" + std::to_string(seed);
  content.rig = subject.rig;
  content.poses = subject.poses;
  content.pose_names = subject.pose_names;
  content.source = {{"kind", "face_model"},
                    {"face_model", face_model_path},
                    {"seed", std::to_string(seed)},
                    {"note", "synthetic subject: random identity, no captures"}};
  return content;
}

namespace {

std::string safe_name(const std::string& name) {
  std::string out;
  for (char c : name)
    out.push_back(std::isalnum(static_cast<unsigned char>(c)) || c == '_' ? c : '-');
  return out;
}

Result<void> write_meshes(ExportFolder& folder, const ExportContent& c, bool ply) {
  const std::string ext = ply ? ".ply" : ".obj";
  auto write = [&](const std::string& path, const MeshData& mesh, const std::string& comment) {
    if (ply) return folder.write_file(path, encode_ply(mesh, comment));
    return folder.write_text(path, encode_obj(mesh, comment));
  };
  if (auto r = write("neutral" + ext, c.rig.neutral_mesh(), "neutral, millimetres"); !r) return r;
  for (int j = 0; j < c.rig.shape_count(); ++j) {
    char index[16];
    std::snprintf(index, sizeof index, "%02d", j + 1);
    const std::string& name = c.rig.shape_names[static_cast<std::size_t>(j)];
    if (auto r = write("blendshapes/" + std::string(index) + "_" + safe_name(name) + ext,
                       c.rig.shape_mesh(j), name + ", millimetres");
        !r) {
      return r;
    }
  }
  for (std::size_t i = 0; i < c.poses.size(); ++i) {
    const std::string name = i < c.pose_names.size() ? c.pose_names[i] : "";
    if (auto r = write("poses/pose_" + std::to_string(i) + ext, c.poses[i], name + ", millimetres");
        !r) {
      return r;
    }
  }
  return success();
}

}  // namespace

Result<ExportSummary> export_content(const ExportContent& c, const ExportRequest& request) {
  const auto start = std::chrono::steady_clock::now();
  auto folder = ExportFolder::create(request.out, request.overwrite);
  if (!folder) return folder.failure();
  ExportManifest manifest;
  manifest.what = to_string(request.format);
  manifest.source = c.source;
  manifest.details = {{"vertices", std::to_string(c.rig.vertex_count())},
                      {"triangles", std::to_string(c.rig.triangles.size() / 3)},
                      {"blendshapes", std::to_string(c.rig.shape_count())},
                      {"poses", std::to_string(c.poses.size())}};
  std::string names;
  for (const auto& n : c.rig.shape_names) names += (names.empty() ? "" : ",") + n;
  manifest.details["blendshape_names"] = names;
  switch (request.format) {
    case ExportFormat::kFaceWarehouse: {
      if (c.rig.shape_count() == 0)
        return fail(
            "FaceWarehouse's layout is a blendshape set and this export has only the "
            "neutral (no rig): use --format obj, ply or glb, or fit the session's "
            "expressions and build a rig first");
      FaceWarehouseTester tester;
      tester.number = request.tester_number;
      tester.rig = c.rig;
      tester.poses = c.poses;
      tester.pose_colors = c.pose_colors;
      tester.pose_landmarks = c.pose_landmarks;
      if (auto r = write_facewarehouse_tester(*folder, tester); !r) return r.failure();
      manifest.details["layout"] =
          "Tester_N/Blendshape/shape_0..K.obj + shape.bs (int32 nShapes,nVerts,nFaces; float32 "
          "(nShapes+1) x nVerts x 3, neutral first, little-endian); Tester_N/TrainingPose/"
          "pose_i.obj (+ .png colour, .land landmarks)";
      break;
    }
    case ExportFormat::kGlb: {
      GlbOptions options;
      options.name = c.name;
      auto glb = encode_glb(c.rig, options);
      if (!glb) return glb.failure();
      if (auto r = folder->write_file(c.name + ".glb", *glb); !r) return r.failure();
      manifest.details["units"] = "metres (glTF)";
      manifest.details["morph_targets"] = c.rig.shape_count() > 0
                                              ? "POSITION deltas, names in mesh.extras.targetNames"
                                              : "none (the neutral alone)";
      break;
    }
    case ExportFormat::kObj:
    case ExportFormat::kPly:
      if (auto r = write_meshes(*folder, c, request.format == ExportFormat::kPly); !r) {
        return r.failure();
      }
      break;
  }
  if (auto r = folder->finish(manifest); !r) return r.failure();
  ExportSummary summary;
  summary.path = folder->destination();
  summary.files = static_cast<int>(folder->files().size()) + 1;
  std::error_code ec;
  summary.bytes =
      folder->total_bytes() + std::filesystem::file_size(summary.path / "manifest.json", ec);
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

}  // namespace fb
