// `facebooth export`: what to export (a stored session's rig, fitted meshes and colour frames,
// or a synthetic subject from the face model) and the formats, each written as a folder with a
// manifest through ExportFolder (temporary name, renamed when complete).
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "algo/core/image.hpp"
#include "algo/core/result.hpp"
#include "storage/export/arkit_rig.hpp"
#include "storage/export/mesh_geometry.hpp"
#include "storage/export/synthetic_subject.hpp"
#include "storage/session_store.hpp"
#include "storage/stored_data.hpp"

namespace fb {

enum class ExportFormat { kFaceWarehouse, kGlb, kObj, kPly };
Result<ExportFormat> parse_export_format(std::string_view name);
const char* to_string(ExportFormat format);

struct ExportContent {
  std::string name = "face";  // file stem for single-file formats
  RigData rig;
  std::vector<MeshData> poses;  // fitted expressions, in capture order
  std::vector<std::string> pose_names;
  std::vector<ColorImage> pose_colors;  // first frame of each capture (may be empty)
  std::vector<std::vector<Landmark>> pose_landmarks;
  std::map<std::string, std::string> source;  // goes into the manifest
  MeshUvs uvs;  // the face model's UV layout when the rig has its topology (else empty)
  // The subject's colour texture in that layout, PNG (empty: none; `facebooth texture` builds
  // it from the session's colour frames). glTF: baseColorTexture; OBJ: face.png + map_Kd.
  std::vector<std::uint8_t> texture_png;
  // Per pose (same order as poses): that expression's own texture, PNG, or empty
  // (FaceWarehouse's TrainingPose/pose_i_texture.png).
  std::vector<std::vector<std::uint8_t>> pose_textures;
  // Per pose: that capture's newest wrinkle detail (`facebooth wrinkles`; width 0: none). The
  // neutral's (pose 0) normal map goes on the glTF material and into the OBJ MTL; every pose's
  // maps are written to wrinkles/ (the blendshapes' detail is blended from them, section 4).
  std::vector<WrinkleDetailData> pose_details;
};

// Attaches the face model's UV layout when the content's rig has the model's triangles (a rig
// fitted to the model, or a synthetic subject); otherwise leaves the content without UVs.
void use_face_model_uvs(ExportContent& content, const FaceModel& model);

// The session's subject's newest rig (preferring one built from this session), the session's
// fitted meshes by capture index (a kNeutral mesh counts as pose 0), and each done capture's
// first colour frame and landmarks. A subject without a rig exports the session's fitted
// neutral as a rig without blendshapes (OBJ, PLY, glTF; FaceWarehouse needs blendshapes).
struct SessionContentOptions {
  // Each done capture's first colour frame and landmarks (FaceWarehouse's pose_i.png/.land):
  // reading them checks every capture's frames file, seconds for a 20-capture session.
  bool capture_frames = true;
};
Result<ExportContent> load_session_content(const SessionStore& store, SessionId session,
                                           const SessionContentOptions& options = {});
ExportContent synthetic_content(const SyntheticSubject& subject, std::uint64_t seed,
                                const std::string& face_model_path);

// The neutral's wrinkle normal map (pose 0's detail), or nullptr: the glTF's normalTexture.
const std::vector<std::uint8_t>* neutral_normal_png(const ExportContent& content);

struct ExportRequest {
  ExportFormat format = ExportFormat::kFaceWarehouse;
  std::filesystem::path out;  // the folder to create
  bool overwrite = false;
  int tester_number = 1;  // FaceWarehouse's Tester_N
  // Blendshape names; unset = the format's default (default_shape_names).
  std::optional<ShapeNames> names;
};

// ARKit's 52 for glTF (what engines and Live Link tools look for), the model's names for OBJ,
// PLY and FaceWarehouse (the fitted shapes as they are).
ShapeNames default_shape_names(ExportFormat format);

struct ExportSummary {
  std::filesystem::path path;
  std::uint64_t bytes = 0;  // all files including the manifest
  int files = 0;
  int blendshapes = 0;  // as exported (52 with ARKit names)
  double seconds = 0.0;
};

// Layouts: facewarehouse -> Tester_N/... (see facewarehouse.hpp); glb -> NAME.glb; obj and ply
// -> neutral.EXT, blendshapes/NN_NAME.EXT, poses/pose_I.EXT. Always plus manifest.json.
Result<ExportSummary> export_content(const ExportContent& content, const ExportRequest& request);

class ExportFolder;
// One wrinkle detail map as files: STEM_normal.png (tangent space, x along +u, y along +v) and
// STEM_displacement.pgm (16-bit, mm = (value - 32768) / 1000).
Result<void> write_detail_map_files(ExportFolder& folder, const std::string& stem,
                                    const WrinkleDetailData& detail);

}  // namespace fb
