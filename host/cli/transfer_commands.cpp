// `facebooth transfer`: a source's expression set mapped onto another face's neutral by
// vertex-tent-coordinate deformation transfer (algo/transfer, seed 002 section IV), written in
// the export formats.
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "algo/transfer/expression_set.hpp"
#include "host/cli/commands.hpp"
#include "host/cli/export_summary.hpp"
#include "host/cli/mesh_landmarks.hpp"
#include "host/cli/tracker_setup.hpp"
#include "storage/asset_files.hpp"
#include "storage/export/export_session.hpp"
#include "storage/export/mesh_files.hpp"

namespace fb::cli {

namespace {

namespace fs = std::filesystem;

constexpr std::string_view kSessionPrefix = "session:";

// A face to read: a stored session ("session:N") or a path.
struct FaceSpec {
  std::optional<SessionId> session;
  fs::path path;
  std::string text;
};

Result<FaceSpec> parse_face_spec(const std::string& text, const char* option) {
  if (text.empty()) return fail(std::string("--") + option + " is required");
  FaceSpec spec{std::nullopt, {}, text};
  if (text.rfind(kSessionPrefix, 0) == 0) {
    const std::string id = text.substr(kSessionPrefix.size());
    char* end = nullptr;
    const long long v = std::strtoll(id.c_str(), &end, 10);
    if (id.empty() || *end != '\0' || v <= 0)
      return fail(std::string("--") + option + " " + text + ": write session:ID, ID > 0");
    spec.session = v;
  } else {
    spec.path = text;
  }
  return spec;
}

Result<MeshData> read_mesh(const fs::path& path) {
  auto read = read_obj(path);
  if (!read) return read.failure();
  if (read->mesh.vertex_count() < 3 || read->mesh.triangle_count() < 1)
    return fail(path.string() + " has no faces: give a mesh with v and f records");
  return std::move(read->mesh);
}

// The expression files of a mesh folder: blendshapes/NN_NAME.obj (the layout `facebooth export
// --format obj` writes) or else every *.obj beside neutral.obj; names from the file stems.
std::vector<std::pair<std::string, fs::path>> expression_files(const fs::path& dir) {
  const bool exported = fs::is_directory(dir / "blendshapes");
  std::vector<std::pair<std::string, fs::path>> files;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(exported ? dir / "blendshapes" : dir, ec)) {
    if (!e.is_regular_file() || e.path().extension() != ".obj") continue;
    std::string name = e.path().stem().string();
    if (!exported && name == "neutral") continue;
    const auto cut = name.find('_');
    if (exported && cut != std::string::npos &&
        std::all_of(name.begin(), name.begin() + static_cast<std::ptrdiff_t>(cut), ::isdigit))
      name = name.substr(cut + 1);
    files.emplace_back(name, e.path());
  }
  std::sort(files.begin(), files.end(),
            [](const auto& a, const auto& b) { return a.second < b.second; });
  return files;
}

Result<RigData> read_mesh_folder(const fs::path& dir) {
  if (!fs::is_directory(dir))
    return fail(dir.string() +
                " is not a folder: --from takes a folder with neutral.obj and the "
                "expressions as OBJ files, or session:ID");
  auto neutral = read_mesh(dir / "neutral.obj");
  if (!neutral) return fail("--from " + dir.string() + ": " + neutral.error().message);
  RigData rig;
  rig.neutral = std::move(neutral->positions);
  rig.triangles = std::move(neutral->triangles);
  for (const auto& [name, path] : expression_files(dir)) {
    auto mesh = read_mesh(path);
    if (!mesh) return mesh.failure();
    if (mesh->positions.size() != rig.neutral.size() || mesh->triangles != rig.triangles)
      return fail(path.string() + " does not share neutral.obj's vertices and faces (" +
                  std::to_string(mesh->vertex_count()) + " vertices against " +
                  std::to_string(rig.vertex_count()) +
                  "): every expression must be the neutral mesh moved");
    rig.shapes.push_back(std::move(mesh->positions));
    rig.shape_names.push_back(name);
  }
  if (rig.shapes.empty())
    return fail("--from " + dir.string() + " has neutral.obj but no expression OBJ files");
  return rig;
}

Result<ExportContent> read_session(const std::string& store_dir, SessionId id) {
  if (store_dir.empty()) return fail("session:" + std::to_string(id) + " needs --store DIR");
  StoreOptions so;
  so.read_only = true;
  so.create = false;
  auto store = SessionStore::open(store_dir, so);
  if (!store) return store.failure();
  return load_session_content(*store, id);
}

Result<RigData> read_source(const FaceSpec& spec, const std::string& store_dir) {
  if (!spec.session) return read_mesh_folder(spec.path);
  auto content = read_session(store_dir, *spec.session);
  if (!content) return content.failure();
  if (content->rig.shapes.empty())
    return fail("session " + std::to_string(*spec.session) +
                " has no rig to transfer from: build one with `facebooth rig --store " + store_dir +
                " --session " + std::to_string(*spec.session) + " --save`");
  return std::move(content->rig);
}

// The target neutral, and the target session's texture when it has one.
Result<std::pair<MeshData, std::vector<std::uint8_t>>> read_target(const FaceSpec& spec,
                                                                   const std::string& store_dir) {
  if (!spec.session) {
    auto mesh = read_mesh(spec.path);
    if (!mesh) return fail("--to " + spec.text + ": " + mesh.error().message);
    return std::pair{std::move(*mesh), std::vector<std::uint8_t>{}};
  }
  auto content = read_session(store_dir, *spec.session);
  if (!content) return content.failure();
  return std::pair{content->rig.neutral_mesh(), std::move(content->texture_png)};
}

bool same_topology(const RigData& source, const MeshData& target) {
  return source.vertex_count() == target.vertex_count() && source.triangles == target.triangles;
}

// Feature points (section V) from a file of "x y z" lines ('#' comments), for meshes of
// different topology.
Result<Points> read_landmarks(const fs::path& path) {
  std::ifstream in(path);
  if (!in) return fail("cannot read " + path.string() + ": give a file of 'x y z' lines");
  std::vector<Eigen::RowVector3d> rows;
  int line_no = 0;
  for (std::string line; std::getline(in, line);) {
    ++line_no;
    if (line.find_first_not_of(" \t\r") == std::string::npos || line[0] == '#') continue;
    std::istringstream ls(line);
    Eigen::RowVector3d p;
    if (!(ls >> p[0] >> p[1] >> p[2]) || !p.allFinite())
      return fail(path.string() + " line " + std::to_string(line_no) + ": expected 'x y z'");
    rows.push_back(p);
  }
  Points out(static_cast<Eigen::Index>(rows.size()), 3);
  for (std::size_t i = 0; i < rows.size(); ++i) out.row(static_cast<Eigen::Index>(i)) = rows[i];
  return out;
}

// A face's feature points: its --*-landmarks file, else the face model's 68 landmark vertices
// when the mesh has the model's topology, else none.
Result<std::optional<Points>> features_of(const std::string& file, std::span<const float> xyz,
                                          const std::vector<std::uint32_t>& triangles,
                                          const FaceModel* model) {
  if (!file.empty()) {
    auto read = read_landmarks(file);
    if (!read) return read.failure();
    return std::optional<Points>(std::move(*read));
  }
  if (model == nullptr || model->triangles != triangles ||
      xyz.size() != static_cast<std::size_t>(model->vertex_count) * 3)
    return std::optional<Points>();
  const Points p = points_from_floats(xyz);
  Points out(68, 3);
  for (int l = 0; l < 68; ++l)
    out.row(l) = p.row(model->landmark_vertices[static_cast<std::size_t>(l)]);
  return std::optional<Points>(out);
}

struct Transferred {
  RigData rig;
  double factor_ms = 0, per_expression_ms = 0;
  std::optional<double> correspondence_ms;
  int unmatched = 0;
};

struct Features {
  std::optional<Points> source, target;
  std::string origin = "given";  // or how they were found
};

std::string topology_hint(const RigData& source, const MeshData& target, const char* which,
                          const std::string& why) {
  return "the target (" + std::to_string(target.vertex_count()) + " vertices, " +
         std::to_string(target.triangle_count()) + " triangles) does not have the source's " +
         "topology (" + std::to_string(source.vertex_count()) + " vertices) and the " + which +
         "'s feature points could not be found: " + why +
         "; give the same 68 points on both, --to-landmarks FILE and, unless the source is on "
         "the face model's mesh, --from-landmarks FILE";
}

// Different topologies without both feature point sets: dlib's 68 points on frontal renders
// (mesh_landmarks.hpp) for every face without a --*-landmarks file, the source's too even on
// the face model's mesh, so that both sets come from the same detector (eval transfer: 0.65-0.75
// mm on the remeshed targets against 0.69-0.81 with the model's vertices on the source).
Result<void> find_missing_features(const ParsedOptions& options, const RigData& source,
                                   const MeshData& target, Features& features) {
  if (same_topology(source, target) || (features.source && features.target)) return success();
  auto detector = load_landmark_detector(options.get("shape-predictor"));
  if (!detector) return detector.failure();
  std::cerr << "transfer: no feature points given for both faces; finding them with dlib on "
               "frontal renders...\n";
  if (options.get("from-landmarks").empty()) {
    auto found =
        landmarks_from_render(*detector, points_from_floats(source.neutral), source.triangles);
    if (!found) return fail(topology_hint(source, target, "source", found.error().message));
    features.source = std::move(*found);
  }
  if (options.get("to-landmarks").empty()) {
    auto found =
        landmarks_from_render(*detector, points_from_floats(target.positions), target.triangles);
    if (!found) return fail(topology_hint(source, target, "target", found.error().message));
    features.target = std::move(*found);
  }
  features.origin = "dlib on frontal renders";
  return success();
}

// One topology: the target is aligned to the source (similarity over all vertices),
// transferred there and moved back, so the source's per-vertex transformations act in the
// target's own axes. Two topologies: section V's correspondence from the feature points.
Result<Transferred> transfer_rig(const RigData& source, const MeshData& target,
                                 const Features& features) {
  const bool same = same_topology(source, target);
  if (!same && (!features.source || !features.target))
    return fail("the target (" + std::to_string(target.vertex_count()) + " vertices, " +
                std::to_string(target.triangle_count()) +
                " triangles) does not have the source's topology (" +
                std::to_string(source.vertex_count()) + " vertices, " +
                std::to_string(source.triangles.size() / 3) +
                " triangles) and no feature points were found: give the same feature points "
                "on both, --to-landmarks FILE and, unless the source is on the face model's "
                "mesh, --from-landmarks FILE");
  auto faces = faces_of(source.vertex_count(), source.triangles, 3);
  if (!faces) return faces.failure();
  auto target_faces = faces_of(target.vertex_count(), target.triangles, 3);
  if (!target_faces) return target_faces.failure();
  std::vector<Points> expressions;
  for (const auto& shape : source.shapes) expressions.push_back(points_from_floats(shape));
  Transferred out;
  Result<ExpressionSetTransfer> moved = fail("not run");
  if (same) {
    moved = transfer_expression_set(tent_topology(*faces), points_from_floats(source.neutral),
                                    expressions, points_from_floats(target.positions));
  } else {
    auto across = transfer_expression_set_across(
        tent_topology(*faces), points_from_floats(source.neutral), expressions, *features.source,
        tent_topology(*target_faces), points_from_floats(target.positions), *features.target);
    if (!across) return across.failure();
    out.correspondence_ms = across->correspondence_ms;
    out.unmatched = across->unmatched;
    moved = static_cast<ExpressionSetTransfer>(std::move(*across));
  }
  if (!moved) return moved.failure();
  out.factor_ms = moved->factor_ms;
  out.per_expression_ms = moved->per_expression_ms;
  out.rig.neutral = target.positions;
  out.rig.triangles = target.triangles;
  out.rig.shape_names = source.shape_names;
  for (const Points& e : moved->expressions) out.rig.shapes.push_back(floats_from_points(e));
  return out;
}

int run_transfer(const ParsedOptions& options) {
  auto from = parse_face_spec(options.get("from"), "from");
  if (!from) return report_failure(from.error());
  auto to = parse_face_spec(options.get("to"), "to");
  if (!to) return report_failure(to.error());
  if (options.get("out").empty()) return report_failure({"--out DIR is required"});
  auto format = parse_export_format(options.get("format"));
  if (!format) return report_failure(format.error());
  ExportRequest request;
  request.format = *format;
  request.out = options.get("out");
  request.overwrite = options.flag("force");
  if (!options.get("names").empty()) {
    auto names = parse_shape_names(options.get("names"));
    if (!names) return report_failure(names.error());
    request.names = *names;
  }
  if (fs::exists(request.out) && !request.overwrite)  // before the work, not after it
    return report_failure({request.out.string() +
                           " already exists: choose another --out, or pass --force to replace it"});
  const std::string store_dir = options.get("store");
  auto source = read_source(*from, store_dir);
  if (!source) return report_failure(source.error());
  auto target = read_target(*to, store_dir);
  if (!target) return report_failure(target.error());
  auto model = load_face_model();  // the landmark vertices and UVs of its mesh, when it loads
  const FaceModel* face_model = model ? &*model : nullptr;
  Features features;
  auto from_features =
      features_of(options.get("from-landmarks"), source->neutral, source->triangles, face_model);
  if (!from_features) return report_failure(from_features.error());
  auto to_features = features_of(options.get("to-landmarks"), target->first.positions,
                                 target->first.triangles, face_model);
  if (!to_features) return report_failure(to_features.error());
  features = {std::move(*from_features), std::move(*to_features)};
  if (auto ok = find_missing_features(options, *source, target->first, features); !ok)
    return report_failure(ok.error());
  std::cerr << "transfer: " << source->shape_count() << " expressions onto "
            << target->first.vertex_count() << " vertices...\n";
  auto result = transfer_rig(*source, target->first, features);
  if (!result) return report_failure(result.error());
  ExportContent content;
  content.rig = std::move(result->rig);
  content.texture_png = std::move(target->second);
  content.source = {{"kind", "transfer"},
                    {"method", "vertex-tent-coordinate deformation transfer"},
                    {"from", from->text},
                    {"to", to->text}};
  if (face_model != nullptr) use_face_model_uvs(content, *face_model);
  auto summary = export_content(content, request);
  if (!summary) return report_failure(summary.error());
  nlohmann::json out = summary_json(*summary);
  out["format"] = to_string(*format);
  out["expressions"] = content.rig.shape_count();
  out["vertices"] = content.rig.vertex_count();
  out["factor_ms"] = result->factor_ms;
  out["per_expression_ms"] = result->per_expression_ms;
  out["uvs"] = !content.uvs.empty();
  if (result->correspondence_ms) {
    out["correspondence_ms"] = *result->correspondence_ms;
    out["unmatched_vertices"] = result->unmatched;
    out["feature_points"] = features.origin;
  }
  std::cout << out.dump(2) << std::endl;
  return kExitOk;
}

}  // namespace

std::vector<Command> transfer_commands() {
  return {
      {{"transfer",
        "map a source's expressions onto another face's neutral (vertex-tent coordinates)",
        "Each source expression becomes one 3x3 transformation per vertex (its one-ring tent "
        "with an apex on the normal, neutral -> expression); the target expression is the "
        "least-squares surface whose tents deform the same way, one sparse system factored once "
        "for the target and solved once per expression (seed 002, section IV). The target is "
        "first aligned to the source by a similarity over all vertices. Meshes of different "
        "topology need the same feature points on both (section V: aligned by them, projected "
        "onto a cylinder, parameterised by their triangulation, each target vertex given a point "
        "on the source): --to-landmarks, and --from-landmarks unless the source is on the face "
        "model's mesh (whose 68 landmark vertices are used); without them dlib finds the 68 "
        "points on a frontal render of each face without a file (the meshes must look along +z "
        "with +y up). OBJ quads are read as triangle pairs. Writes the "
        "target neutral and the transferred expressions as blendshapes in --format's layout "
        "(see `facebooth export`); JSON summary on stdout.",
        {{"from", "SRC",
          "the source: a folder with neutral.obj and the expressions as OBJ files (or "
          "blendshapes/NN_NAME.obj, as `export --format obj` writes), or session:ID (that "
          "session's subject's rig, in --store)",
          ""},
         {"to", "TARGET",
          "the target neutral: an OBJ file, or session:ID (that subject's neutral in --store; its "
          "texture is carried into the export)",
          ""},
         {"store", "DIR", "session store for session:ID sources and targets", ""},
         {"out", "DIR", "output folder (must not exist unless --force)", ""},
         {"format", "F", "facewarehouse, glb, obj or ply", "obj"},
         {"names", "N",
          "model or arkit (default: the format's, arkit for glb; arkit needs the face model's "
          "names)",
          ""},
         {"from-landmarks", "FILE",
          "the source's feature points, one 'x y z' line each (default: the face model's 68 "
          "landmark vertices when the source is on its mesh)",
          ""},
         {"to-landmarks", "FILE",
          "the target's feature points, the same points in the same order (needed when the "
          "target's topology differs from the source's)",
          ""},
         {"shape-predictor", "PATH",
          "dlib's 68-point model for faces without feature points (default: Debian "
          "libdlib-data's)",
          ""},
         {"force", "", "replace --out if it exists", ""}}},
       run_transfer}};
}

}  // namespace fb::cli
