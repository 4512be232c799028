#include "storage/export/export_session.hpp"

#include <map>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>

#include "algo/wrinkles/detail_mesh.hpp"
#include "storage/export/export_folder.hpp"
#include "storage/export/facewarehouse.hpp"
#include "storage/export/gltf.hpp"
#include "storage/export/mesh_files.hpp"
#include "storage/export/png_file.hpp"

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

Result<ExportContent> load_session_content(const SessionStore& store, SessionId session,
                                           const SessionContentOptions& options) {
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

  // The newest subject texture (and per capture the newest expression texture).
  auto textures = store.textures(session);
  if (!textures) return textures.failure();
  std::map<int, TextureId> capture_texture;
  std::optional<TextureId> subject_texture;
  for (const auto& t : *textures) {
    if (t.capture_index)
      capture_texture[*t.capture_index] = t.id;
    else
      subject_texture = t.id;
  }
  if (subject_texture) {
    auto png = store.read_texture(*subject_texture);
    if (!png) return png.failure();
    content.texture_png = std::move(*png);
    content.source["texture"] = std::to_string(*subject_texture);
  }

  // The newest wrinkle detail per capture.
  auto details = store.wrinkle_details(session);
  if (!details) return details.failure();
  std::map<int, WrinkleDetailId> capture_detail;
  for (const auto& d : *details) capture_detail[d.capture_index] = d.id;

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
    if (c.state == CaptureState::kDone && options.capture_frames) {
      auto data = store.read_capture(session, c.index, {.max_frames = 1});  // colour of frame 0
      if (!data) return data.failure();
      if (!data->frames.empty()) color = std::move(data->frames.front().color);
      landmarks = std::move(data->landmarks);
    }
    std::vector<std::uint8_t> texture;
    if (auto t = capture_texture.find(c.index); t != capture_texture.end()) {
      auto png = store.read_texture(t->second);
      if (!png) return png.failure();
      texture = std::move(*png);
    } else if (c.index == 0) {
      texture = content.texture_png;  // the subject texture is the neutral's
    }
    content.pose_textures.push_back(std::move(texture));
    WrinkleDetailData detail;
    if (auto d = capture_detail.find(c.index); d != capture_detail.end()) {
      auto read = store.read_wrinkle_detail(d->second);
      if (!read) return read.failure();
      detail = std::move(*read);
      content.source["wrinkles_" + std::to_string(c.index)] = std::to_string(d->second);
    }
    content.pose_details.push_back(std::move(detail));
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

void use_face_model_uvs(ExportContent& content, const FaceModel& model) {
  if (model.uvs.empty() || model.triangles != content.rig.triangles) return;
  content.uvs.uvs = model.atlas_uvs();  // one [0, 1] square: the texture atlas's layout
  content.uvs.triangle_uvs = model.triangle_uvs;
}

const std::vector<std::uint8_t>* neutral_normal_png(const ExportContent& c) {
  if (c.pose_details.empty() || c.pose_names.empty() || c.pose_names.front() != "neutral" ||
      c.pose_details.front().normal_png.empty())
    return nullptr;
  return &c.pose_details.front().normal_png;
}

ShapeNames default_shape_names(ExportFormat format) {
  return format == ExportFormat::kGlb ? ShapeNames::kArkit : ShapeNames::kModel;
}

namespace {

constexpr const char* kMaterialName = "skin";
constexpr const char* kMtlFile = "face.mtl";
constexpr const char* kTextureFile = "face.png";

// A plain skin-tone material (Kd matches the glTF baseColorFactor), with the texture when there
// is one (white Kd then, as glTF's factor, so the texture is not tinted).
constexpr const char* kNormalFile = "face_normal.png";

constexpr const char* kDisplacedMaterialName = "skin_displaced";

std::string material(const char* name, bool texture, bool normal_map) {
  return std::string("newmtl ") + name + "\nKa 0 0 0\n" +
         (texture ? "Kd 1 1 1\n" : "Kd 0.8 0.6 0.5\n") +
         "Ks 0.05 0.05 0.05\n"
         "Ns 20\n"
         "d 1\n"
         "illum 2\n" +
         (texture ? std::string("map_Kd ") + kTextureFile + "\n" : std::string()) +
         // `norm`: the tangent-space normal map extension (Blender, assimp read it).
         (normal_map ? std::string("norm ") + kNormalFile + "\n" : std::string());
}

// skin; with displaced meshes also skin_displaced, without the normal map (their geometry
// carries the detail already: the map on top would double it).
std::string skin_mtl(bool texture, bool normal_map, bool displaced) {
  return "# facebooth: the skin material of the exported meshes\n" +
         material(kMaterialName, texture, normal_map) +
         (displaced ? "\n" + material(kDisplacedMaterialName, texture, false) : std::string());
}

bool has_detail_meshes(const ExportContent& c) {
  for (std::size_t i = 0; i < c.poses.size() && i < c.pose_details.size(); ++i)
    if (c.pose_details[i].width > 0 && c.uvs.fits(c.poses[i].triangles)) return true;
  return false;
}

// poses/pose_I_detail.obj for every pose with wrinkle detail: the pose's mesh subdivided under
// the detail and displaced by its heights (algo/wrinkles/detail_mesh.hpp), for tools that read
// OBJ geometry and no displacement map.
Result<int> write_detail_meshes(ExportFolder& folder, const ExportContent& c) {
  int written = 0;
  for (std::size_t i = 0; i < c.poses.size() && i < c.pose_details.size(); ++i) {
    const WrinkleDetailData& d = c.pose_details[i];
    if (d.width <= 0 || !c.uvs.fits(c.poses[i].triangles)) continue;
    FloatImage disp;
    disp.resize(d.width, d.height);
    disp.pixels = d.displacement_mm;
    DetailMeshInput in;
    in.vertices = c.poses[i].positions;
    in.triangles = c.poses[i].triangles;
    in.uvs = c.uvs.uvs;
    in.triangle_uvs = c.uvs.triangle_uvs;
    in.displacement_mm = &disp;
    auto mesh = subdivided_detail_mesh(in);
    if (!mesh) return mesh.failure();
    MeshUvs uvs;
    uvs.uvs = std::move(mesh->uvs);
    uvs.triangle_uvs = std::move(mesh->triangle_uvs);
    ObjExtras extras;
    extras.uvs = &uvs;
    extras.normals = true;
    extras.mtllib = std::string("../") + kMtlFile;
    extras.material = kDisplacedMaterialName;
    const std::string name = i < c.pose_names.size() ? c.pose_names[i] : "";
    const MeshData out{std::move(mesh->positions), std::move(mesh->triangles)};
    if (auto r = folder.write_text(
            "poses/pose_" + std::to_string(i) + "_detail.obj",
            encode_obj(out,
                       name + ", millimetres; subdivided under the wrinkle detail and displaced",
                       &extras));
        !r)
      return r.failure();
    ++written;
  }
  return written;
}

}  // namespace

Result<void> write_detail_map_files(ExportFolder& folder, const std::string& stem,
                                    const WrinkleDetailData& d) {
  if (auto r = folder.write_file(stem + "_normal.png", d.normal_png); !r) return r.failure();
  DepthImage pgm;
  pgm.resize(d.width, d.height);
  for (std::size_t k = 0; k < d.displacement_mm.size(); ++k)
    pgm.pixels[k] = static_cast<std::uint16_t>(
        std::clamp(std::lround(32768.0 + 1000.0 * d.displacement_mm[k]), 0L, 65535L));
  return folder.write_text(stem + "_displacement.pgm", encode_pgm16(pgm));
}

namespace {

// Every pose's wrinkle detail: wrinkles/pose_I_normal.png (tangent space, x along +u, y along
// +v) and wrinkles/pose_I_displacement.pgm (16-bit, mm = (value - 32768) / 1000).
Result<int> write_wrinkle_maps(ExportFolder& folder, const ExportContent& c) {
  int written = 0;
  for (std::size_t i = 0; i < c.pose_details.size(); ++i) {
    const WrinkleDetailData& d = c.pose_details[i];
    if (d.width <= 0) continue;
    if (auto r = write_detail_map_files(folder, "wrinkles/pose_" + std::to_string(i), d); !r)
      return r.failure();
    ++written;
  }
  return written;
}

std::string safe_name(const std::string& name) {
  std::string out;
  for (char c : name)
    out.push_back(std::isalnum(static_cast<unsigned char>(c)) || c == '_' ? c : '-');
  return out;
}

Result<void> write_meshes(ExportFolder& folder, const ExportContent& c, const RigData& rig,
                          bool ply) {
  const std::string ext = ply ? ".ply" : ".obj";
  // OBJ: normals, the UV layout (when it fits) and the skin material from face.mtl, referenced
  // relative to each file's folder.
  if (!ply) {
    const bool texture = !c.texture_png.empty() && c.uvs.fits(rig.triangles);
    const auto* normal = c.uvs.fits(rig.triangles) ? neutral_normal_png(c) : nullptr;
    if (auto r =
            folder.write_text(kMtlFile, skin_mtl(texture, normal != nullptr, has_detail_meshes(c)));
        !r)
      return r;
    if (texture) {
      if (auto r = folder.write_file(kTextureFile, c.texture_png); !r) return r;
    }
    if (normal != nullptr) {
      if (auto r = folder.write_file(kNormalFile, *normal); !r) return r;
    }
  }
  auto write = [&](const std::string& path, const MeshData& mesh, const std::string& comment) {
    if (ply) return folder.write_file(path, encode_ply(mesh, comment));
    ObjExtras extras;
    extras.uvs = c.uvs.fits(mesh.triangles) ? &c.uvs : nullptr;
    extras.normals = true;
    extras.mtllib = path.find('/') == std::string::npos ? kMtlFile : std::string("../") + kMtlFile;
    extras.material = kMaterialName;
    return folder.write_text(path, encode_obj(mesh, comment, &extras));
  };
  if (auto r = write("neutral" + ext, rig.neutral_mesh(), "neutral, millimetres"); !r) return r;
  for (int j = 0; j < rig.shape_count(); ++j) {
    char index[16];
    std::snprintf(index, sizeof index, "%02d", j + 1);
    const std::string& name = rig.shape_names[static_cast<std::size_t>(j)];
    if (auto r = write("blendshapes/" + std::string(index) + "_" + safe_name(name) + ext,
                       rig.shape_mesh(j), name + ", millimetres");
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
  if (!ply) {
    if (auto r = write_detail_meshes(folder, c); !r) return r.failure();
  }
  return success();
}

}  // namespace

namespace {

std::string joined(const std::vector<std::string>& items, const char* separator = ",") {
  std::string out;
  for (const auto& item : items) out += (out.empty() ? "" : separator) + item;
  return out;
}

// What a FaceWarehouse-layout export holds and how it differs from the original dataset, for
// readers that assume FaceWarehouse's own mesh and expression set.
void describe_facewarehouse(const RigData& rig, const ExportContent& c, ExportManifest& manifest) {
  const bool ict_skin = rig.vertex_count() == 11248;
  manifest.details["layout"] =
      "Tester_N/Blendshape/shape_0..K.obj + shape.bs (int32 nShapes,nVerts,nFaces; float32 "
      "(nShapes+1) x nVerts x 3, neutral first, little-endian); Tester_N/TrainingPose/"
      "pose_i.obj (+ .png colour, .land landmarks, and with a texture .mtl + _texture.png, "
      "the OBJ then carrying vt/vn); Tester_N/Blendshape/shape_names.txt";
  int textured = 0;
  for (const auto& t : c.pose_textures) textured += !t.empty();
  manifest.details["textures"] =
      textured > 0 ? std::to_string(textured) +
                         " training poses carry their own texture (facebooth texture "
                         "--expressions: the capture's colour frames in the face model's UV "
                         "layout, lighting divided out)"
                   : std::string("none (build them with facebooth texture --expressions)");
  manifest.details["topology"] =
      (ict_skin ? std::string("the ICT FaceKit skin (face, back of head and neck; eyes, mouth "
                              "socket and teeth left out): ")
                : std::string("the rig's own mesh: ")) +
      std::to_string(rig.vertex_count()) + " vertices, " +
      std::to_string(rig.triangles.size() / 3) + " triangles (shape_0.obj)";
  manifest.details["units"] =
      "millimetres; model frame +X subject's left, +Y up, +Z out of the face";
  manifest.details["expressions"] =
      "shape_1..shape_" + std::to_string(rig.shape_count()) + " = " + joined(rig.shape_names);
  manifest.details["poses_note"] =
      "TrainingPose/pose_i = the session's fitted captures in capture order (" +
      joined(c.pose_names) + "), not FaceWarehouse's 20 training poses";
  manifest.details["differs_from_facewarehouse"] =
      "FaceWarehouse (Cao et al. 2014) has its own 11,510-vertex mesh and 46 FACS-style "
      "expression blendshapes (shape_0 neutral + 46); this export has " +
      std::to_string(rig.vertex_count()) + " vertices and " + std::to_string(rig.shape_count()) +
      " blendshapes named in shape_names.txt (the ICT FaceKit / ARKit-style set), with no "
      "vertex or expression correspondence to FaceWarehouse. Readers that take the counts "
      "from shape.bs's header (e.g. face_toolkit's loadBlendshapeFW: absolute shapes, shape 0 "
      "the neutral) read it; readers that hard-code 11,510 vertices or 46 shapes refuse it.";
}

// The rig under the requested names, and what the naming did, for the manifest.
Result<RigData> named_rig(const ExportContent& c, ShapeNames names, ExportManifest& manifest) {
  manifest.details["names"] = to_string(names);
  if (names == ShapeNames::kModel || c.rig.shape_count() == 0) return c.rig;
  auto arkit = to_arkit_rig(c.rig);
  if (!arkit) return arkit.failure();
  manifest.details["names_note"] =
      "Apple's 52 ARKit blendshapes in Apple's order (ARFaceAnchor.BlendShapeLocation); "
      "tongueOut is a zero target (the skin has no tongue); combined: " +
      joined(arkit->combined, "; ") +
      (arkit->dropped.empty() ? std::string()
                              : "; left out (no ARKit name): " + joined(arkit->dropped));
  return std::move(arkit->rig);
}

}  // namespace

Result<ExportSummary> export_content(const ExportContent& c, const ExportRequest& request) {
  const auto start = std::chrono::steady_clock::now();
  auto folder = ExportFolder::create(request.out, request.overwrite);
  if (!folder) return folder.failure();
  ExportManifest manifest;
  manifest.what = to_string(request.format);
  manifest.source = c.source;
  auto named = named_rig(c, request.names.value_or(default_shape_names(request.format)), manifest);
  if (!named) return named.failure();
  const RigData& rig = *named;
  manifest.details["vertices"] = std::to_string(rig.vertex_count());
  manifest.details["triangles"] = std::to_string(rig.triangles.size() / 3);
  manifest.details["blendshapes"] = std::to_string(rig.shape_count());
  manifest.details["poses"] = std::to_string(c.poses.size());
  manifest.details["blendshape_names"] = joined(rig.shape_names);
  const bool has_uvs = c.uvs.fits(rig.triangles);
  switch (request.format) {
    case ExportFormat::kFaceWarehouse: {
      if (rig.shape_count() == 0)
        return fail(
            "FaceWarehouse's layout is a blendshape set and this export has only the "
            "neutral (no rig): use --format obj, ply or glb, or fit the session's "
            "expressions and build a rig first");
      FaceWarehouseTester tester;
      tester.number = request.tester_number;
      tester.rig = rig;
      tester.poses = c.poses;
      tester.pose_colors = c.pose_colors;
      tester.pose_landmarks = c.pose_landmarks;
      tester.pose_textures = c.pose_textures;
      tester.uvs = &c.uvs;
      if (auto r = write_facewarehouse_tester(*folder, tester); !r) return r.failure();
      describe_facewarehouse(rig, c, manifest);
      break;
    }
    case ExportFormat::kGlb: {
      GlbOptions options;
      options.name = c.name;
      options.uvs = &c.uvs;
      options.base_color_png = &c.texture_png;
      options.normal_png = neutral_normal_png(c);
      auto glb = encode_glb(rig, options);
      if (!glb) return glb.failure();
      if (auto r = folder->write_file(c.name + ".glb", *glb); !r) return r.failure();
      manifest.details["units"] = "metres (glTF)";
      manifest.details["morph_targets"] =
          rig.shape_count() > 0 ? "POSITION and NORMAL deltas, names in mesh.extras.targetNames"
                                : "none (the neutral alone)";
      manifest.details["attributes"] =
          has_uvs ? "POSITION, NORMAL, TEXCOORD_0 (the face model's UV layout; seam vertices "
                    "split, one glTF vertex per UV)"
                  : "POSITION, NORMAL (no UV layout: the rig is not on the face model's mesh)";
      manifest.details["material"] =
          has_uvs && !c.texture_png.empty()
              ? "skin: PBR metallic-roughness with the subject's texture as baseColorTexture"
              : "skin: PBR metallic-roughness, base colour only (no texture)";
      break;
    }
    case ExportFormat::kObj:
    case ExportFormat::kPly:
      if (auto r = write_meshes(*folder, c, rig, request.format == ExportFormat::kPly); !r) {
        return r.failure();
      }
      if (request.format == ExportFormat::kObj) {
        manifest.details["attributes"] =
            has_uvs ? "v, vt (the face model's UV layout), vn" : "v, vn";
        manifest.details["material"] = has_uvs && !c.texture_png.empty()
                                           ? "face.mtl (skin, map_Kd face.png)"
                                           : "face.mtl (skin, diffuse colour)";
        if (has_uvs && has_detail_meshes(c))
          manifest.details["detail_meshes"] =
              "poses/pose_I_detail.obj per pose with wrinkle detail: the pose's mesh with the "
              "triangles under the detail (and one ring around) subdivided twice at their edge "
              "midpoints, UVs interpolated, vertices moved along their normals by the "
              "displacement map (smoothed over 2 rings at the detail's border); material "
              "skin_displaced (no normal map: the geometry carries the detail)";
      }
      break;
  }
  if (request.format != ExportFormat::kFaceWarehouse && has_uvs) {
    auto maps = write_wrinkle_maps(*folder, c);
    if (!maps) return maps.failure();
    if (*maps > 0) {
      manifest.details["wrinkles"] =
          std::to_string(*maps) +
          " poses carry wrinkle detail (facebooth wrinkles): wrinkles/pose_I_normal.png "
          "(tangent space, x along +u, y along +v of the UV layout) and "
          "wrinkles/pose_I_displacement.pgm (16-bit, mm = (value - 32768) / 1000, along the "
          "normal); the neutral's normal map is on the skin material (glTF normalTexture with "
          "TANGENT, OBJ norm face_normal.png). A frame's detail is N + sum a_i B_i over the "
          "blendshapes, B solved from the poses' maps and their guide weights (docs/wrinkles.md)";
    }
  }
  if (auto r = folder->finish(manifest); !r) return r.failure();
  ExportSummary summary;
  summary.path = folder->destination();
  summary.files = static_cast<int>(folder->files().size()) + 1;
  summary.blendshapes = rig.shape_count();
  std::error_code ec;
  summary.bytes =
      folder->total_bytes() + std::filesystem::file_size(summary.path / "manifest.json", ec);
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

}  // namespace fb
