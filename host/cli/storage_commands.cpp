// facebooth export | import | store info: the session store and the exporters
// (storage/). JSON on stdout, progress on stderr.
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <optional>

#include "algo/core/clock.hpp"
#include "algo/tracking/arkit.hpp"
#include "host/cli/commands.hpp"
#include "host/cli/detail_weights.hpp"
#include "host/cli/export_summary.hpp"
#include "host/cli/stats.hpp"
#include "host/cli/take_columns.hpp"
#include "host/cli/take_gltf.hpp"
#include "storage/asset_files.hpp"
#include "storage/durable_file.hpp"
#include "storage/export/export_folder.hpp"
#include "storage/export/export_session.hpp"
#include "storage/export/facewarehouse.hpp"
#include "storage/export/livelink_csv.hpp"
#include "storage/export/synthetic_subject.hpp"
#include "storage/session_store.hpp"

namespace fb::cli {

Result<std::uintmax_t> folder_bytes(const std::filesystem::path& dir) {
  std::uintmax_t total = 0;
  std::error_code ec;
  for (auto it = std::filesystem::recursive_directory_iterator(dir, ec);
       !ec && it != std::filesystem::recursive_directory_iterator(); it.increment(ec)) {
    if (it->is_regular_file(ec)) total += it->file_size(ec);
  }
  if (ec) return fail("cannot measure " + dir.string() + ": " + ec.message());
  return total;
}

nlohmann::json summary_json(const ExportSummary& s) {
  return {
      {"path", s.path.string()}, {"bytes", s.bytes}, {"files", s.files}, {"seconds", s.seconds}};
}

Result<FaceModelSubject> face_model_subject(const ParsedOptions& options, std::uint64_t seed,
                                            std::string_view log) {
  FaceModelSubject out;
  out.model_path = options.get("face-model").empty() ? default_face_model_path().string()
                                                     : options.get("face-model");
  std::cerr << log << out.model_path << "...\n";
  auto model = load_face_model(out.model_path);
  if (!model) return model.failure();
  out.model = std::move(*model);
  SyntheticSubjectOptions subject_options;
  subject_options.seed = seed;
  auto subject = make_synthetic_subject(out.model, subject_options);
  if (!subject) return subject.failure();
  out.subject = std::move(*subject);
  return out;
}

namespace {

namespace fs = std::filesystem;

std::string default_store() {
  const char* env = std::getenv("FACEBOOTH_STORE");
  return env != nullptr && *env != '\0' ? env : "/var/lib/facebooth/store";
}

OptionSpec store_option() {
  return {"store", "DIR", "session store folder ($FACEBOOTH_STORE sets the default)",
          default_store()};
}

int usage_error(const std::string& message) {
  std::cerr << "facebooth: " << message << "\n";
  return kExitUsage;
}

// ---------------------------------------------------------------------------------------------
// facebooth export

Result<SessionStore> open_reader(const ParsedOptions& options) {
  StoreOptions ro;
  ro.read_only = true;  // exports never write the store; the daemon may be running
  return SessionStore::open(options.get("store"), ro);
}

// What a take's session adds beside its CSV: the face model (for the glb's UV layout and the
// map weights) and, when the session has wrinkle detail on its neutral and expressions, the
// blend of its maps; with what the manifest says about the map weights.
struct TakeSessionParts {
  std::optional<FaceModel> model;
  std::string model_problem;
  std::optional<SessionDetailBlend> detail;
  std::string detail_note;
};

Result<TakeSessionParts> take_session_parts(const SessionStore& store, const TakeData& take) {
  TakeSessionParts out;
  if (!take.info.session) {
    out.detail_note = "none: the take has no session";
    return out;
  }
  const SessionId session = *take.info.session;
  auto model = load_face_model();
  if (!model)
    out.model_problem = "the face model cannot be read (" + model.error().message + ")";
  else
    out.model = std::move(*model);
  auto details = store.wrinkle_details(session);
  if (!details) return details.failure();
  if (details->empty()) {
    out.detail_note =
        "none: session " + std::to_string(session) + " has no wrinkle detail (facebooth wrinkles)";
    return out;
  }
  if (!out.model) return fail(out.model_problem);
  auto guide = load_guide_expressions(*out.model);
  if (!guide) return guide.failure();
  auto blend = load_session_detail_blend(store, session, *out.model, *guide);
  if (!blend) {
    out.detail_note = "none: " + blend.error().message;
    return out;
  }
  out.detail = std::move(*blend);
  return out;
}

// The wrinkle map weights of a take whose session has detail maps (issue 40 item 5), beside
// its CSV; what the manifest says about them.
Result<std::string> take_detail_weights(const TakeData& take, const TakeSessionParts& parts,
                                        ExportFolder& folder) {
  if (!parts.detail) return parts.detail_note;
  auto layers = write_take_detail_weights(folder, take, *parts.detail, *parts.model);
  if (!layers) return layers.failure();
  return "take_" + std::to_string(take.info.id) +
         "_detail_weights.csv: " + detail_weights_description() +
         "; the maps: wrinkles/capture_I_normal.png (tangent space, x along +u, y along +v) and "
         "wrinkles/capture_I_displacement.pgm (16-bit, mm = (value - 32768) / 1000), capture " +
         std::to_string(parts.detail->neutral_capture) + " is N";
}

// Writes the manifest and says what the export holds (`files` including the manifest).
Result<ExportSummary> finish_export(ExportFolder& folder, const ExportManifest& manifest, int files,
                                    Clock::time_point start) {
  if (auto r = folder.finish(manifest); !r) return r.failure();
  ExportSummary summary;
  summary.path = folder.destination();
  summary.files = files;
  summary.bytes = folder.total_bytes();
  summary.seconds = seconds_since(start);
  return summary;
}

// A stored tracking take as Live Link Face CSV (the tracker's ARKit curves by name), and as
// an animated glTF of its session's rig when there is one (take_gltf.hpp).
Result<ExportSummary> export_take(const SessionStore& store, TakeId id, const fs::path& out,
                                  bool overwrite, TakeGlb& glb) {
  const auto start = Clock::now();
  auto take = store.read_take(id);
  if (!take) return take.failure();
  const TakeInfo& info = take->info;
  const std::array<int, kArkitShapeCount> column = arkit_columns(info.shape_names);
  const int matched =
      static_cast<int>(std::count_if(column.begin(), column.end(), [](int c) { return c >= 0; }));
  if (matched == 0) {
    return fail("take " + std::to_string(id) +
                " has no ARKit curve names (e.g. jawOpen), so it cannot be written as Live Link "
                "CSV; export it from the tracker's output instead");
  }
  // The Timecode is the time of day the take was recorded: the store's created_at is when it
  // was stored, just after its last frame (frame times are the take's measured ones).
  double start_of_day_s = 0.0;
  if (auto stored = local_time_of_day_s(info.created_at); stored && info.frame_count > 0) {
    start_of_day_s =
        *stored - take->times_s[static_cast<std::size_t>(info.frame_count - 1)] - 1.0 / info.fps;
    if (start_of_day_s < 0.0) start_of_day_s += 86400.0;
  }
  std::string text = livelink_csv_header() + "\n";
  for (int f = 0; f < info.frame_count; ++f) {
    ArkitFrame frame;
    frame.index = static_cast<std::uint64_t>(f);
    frame.time_s = take->times_s[static_cast<std::size_t>(f)];  // measured, not f / fps
    frame.face_found = true;
    frame.weights = arkit_curves(*take, column, f);
    frame.camera_from_model = take_pose(*take, f);
    text += format_livelink_row(to_livelink_row(frame), info.fps, start_of_day_s) + "\n";
  }
  auto folder = ExportFolder::create(out, overwrite);
  if (!folder) return folder.failure();
  if (auto r = folder->write_text("take_" + std::to_string(id) + ".csv", text); !r) {
    return r.failure();
  }
  auto parts = take_session_parts(store, *take);
  if (!parts) return parts.failure();
  auto detail = take_detail_weights(*take, *parts, *folder);
  if (!detail) return detail.failure();
  auto animated = write_take_glb({&store, &*take, parts->model ? &*parts->model : nullptr,
                                  parts->model_problem, parts->detail ? &*parts->detail : nullptr},
                                 *folder);
  if (!animated) return animated.failure();
  glb = std::move(*animated);
  ExportManifest manifest;
  manifest.what = glb.file.empty() ? "livelink_csv" : "livelink_csv+glb";
  manifest.source = {{"kind", "take"},
                     {"store", store.root().string()},
                     {"take", std::to_string(id)},
                     {"subject", std::to_string(info.subject)}};
  manifest.details = {{"fps", std::to_string(info.fps)},
                      {"frames", std::to_string(info.frame_count)},
                      {"curves_matched", std::to_string(matched)},
                      {"recorded_at", info.created_at},
                      {"timecode", "local time of day, HH:MM:SS:FF.mmm at the take's fps"},
                      {"columns",
                       "the Live Link Face app's order (JawRight before JawLeft, MouthRight "
                       "before MouthLeft); tongueOut is 0 (the skin has no tongue)"},
                      {"format", "Live Link Face CSV (see storage/export/livelink_csv.hpp)"},
                      {"detail_weights", *detail},
                      {"glb", glb.manifest}};
  return finish_export(*folder, manifest, static_cast<int>(folder->files().size()) + 1, start);
}

// A stored model (e.g. the bilinear model) as its file plus a manifest.
Result<ExportSummary> export_model(const SessionStore& store, ModelId id, const fs::path& out,
                                   bool overwrite) {
  const auto start = Clock::now();
  auto models = store.models();
  if (!models) return models.failure();
  const ModelInfo* info = nullptr;
  for (const auto& m : *models) {
    if (m.id == id) info = &m;
  }
  if (info == nullptr) return fail("there is no model " + std::to_string(id) + " in this store");
  auto bytes = store.read_model(id);
  if (!bytes) return bytes.failure();
  auto folder = ExportFolder::create(out, overwrite);
  if (!folder) return folder.failure();
  if (auto r = folder->write_file(info->kind + ".bin", *bytes); !r) return r.failure();
  ExportManifest manifest;
  manifest.what = "model";
  manifest.source = {
      {"kind", "model"}, {"store", store.root().string()}, {"model", std::to_string(id)}};
  manifest.details = {
      {"model_kind", info->kind}, {"params", info->params_json}, {"created_at", info->created_at}};
  return finish_export(*folder, manifest, 2, start);
}

int run_export_stored_item(const ParsedOptions& options) {
  if (options.get("out").empty()) return usage_error("--out DIR is required");
  if (!options.get("names").empty() && options.get("names") != "arkit") {
    return usage_error(
        "--take and --model exports have ARKit curve names only (Live Link Face "
        "CSV columns are ARKit's); leave out --names " +
        options.get("names"));
  }
  auto store = open_reader(options);
  if (!store) return report_failure(store.error());
  const bool take = !options.get("take").empty();
  auto id = options.get_int(take ? "take" : "model");
  if (!id) return report_failure(id.error());
  TakeGlb glb;
  auto summary = take ? export_take(*store, *id, options.get("out"), options.flag("force"), glb)
                      : export_model(*store, *id, options.get("out"), options.flag("force"));
  if (!summary) return report_failure(summary.error());
  nlohmann::json out = summary_json(*summary);
  out["format"] = take ? "livelink" : "model";
  if (take) {
    out["glb"] = glb.file.empty() ? nlohmann::json(nullptr) : nlohmann::json(glb.file);
    if (glb.file.empty()) {
      out["glb_note"] = glb.manifest;
    } else {
      out["glb_vertices"] = glb.vertices;
      out["glb_detail"] = glb.detail;
    }
  }
  std::cout << out.dump(2) << std::endl;
  return kExitOk;
}

int run_export(const ParsedOptions& options) {
  const int items = !options.get("take").empty() + !options.get("model").empty() +
                    !options.get("session").empty() + options.flag("from-face-model");
  if (items > 1) {
    return usage_error("give one of --session, --from-face-model, --take or --model");
  }
  if (!options.get("take").empty() || !options.get("model").empty()) {
    return run_export_stored_item(options);
  }
  auto format = parse_export_format(options.get("format"));
  if (!format) return report_failure(format.error());
  if (options.get("out").empty()) return usage_error("--out DIR is required");
  const bool from_model = options.flag("from-face-model");
  const bool has_session = !options.get("session").empty();
  if (from_model == has_session) {
    return usage_error(
        "give either --session ID (export a stored session) or --from-face-model (a synthetic "
        "subject built from the face model)");
  }
  ExportRequest request;
  request.format = *format;
  request.out = options.get("out");
  request.overwrite = options.flag("force");
  auto tester = options.get_int("tester");
  if (!tester) return report_failure(tester.error());
  request.tester_number = static_cast<int>(*tester);
  if (!options.get("names").empty()) {
    auto names = parse_shape_names(options.get("names"));
    if (!names) return report_failure(names.error());
    request.names = *names;
  }

  ExportContent content;
  if (from_model) {
    auto seed = options.get_int("seed");
    if (!seed) return report_failure(seed.error());
    auto made = face_model_subject(options, static_cast<std::uint64_t>(*seed),
                                   "export: loading the face model ");
    if (!made) return report_failure(made.error());
    content = synthetic_content(made->subject, static_cast<std::uint64_t>(*seed), made->model_path);
    use_face_model_uvs(content, made->model);
  } else {
    auto session = options.get_int("session");
    if (!session) return report_failure(session.error());
    auto store = open_reader(options);
    if (!store) return report_failure(store.error());
    std::cerr << "export: reading session " << *session << " from " << options.get("store")
              << "...\n";
    // Only FaceWarehouse's layout has the captures' colour frames and landmarks; reading them
    // opens every capture's frames file (seconds for a session).
    auto loaded = load_session_content(*store, *session,
                                       {.capture_frames = *format == ExportFormat::kFaceWarehouse});
    if (!loaded) return report_failure(loaded.error());
    content = std::move(*loaded);
    // The UV layout comes from the face model the rig was fitted to.
    if (auto model = load_face_model(); model) {
      use_face_model_uvs(content, *model);
    } else {
      std::cerr << "export: " << model.error().message << "; exporting without UVs\n";
    }
  }
  std::cerr << "export: writing " << to_string(*format) << " to " << request.out.string()
            << "...\n";
  auto summary = export_content(content, request);
  if (!summary) return report_failure(summary.error());
  nlohmann::json out = summary_json(*summary);
  out["format"] = to_string(*format);
  out["source"] = content.source;
  out["names"] = to_string(request.names.value_or(default_shape_names(*format)));
  out["uvs"] = !content.uvs.empty();
  out["blendshapes"] = summary->blendshapes;
  out["poses"] = content.poses.size();
  std::cout << out.dump(2) << std::endl;
  return kExitOk;
}

// ---------------------------------------------------------------------------------------------
// facebooth import

int run_import(const ParsedOptions& options) {
  if (options.get("format") != "facewarehouse") {
    return report_failure({"only --format facewarehouse can be imported"});
  }
  if (options.get("in").empty()) return usage_error("--in DIR is required");
  std::cerr << "import: reading " << options.get("in") << "...\n";
  auto testers = import_facewarehouse(options.get("in"));
  if (!testers) return report_failure(testers.error());
  nlohmann::json out;
  out["testers"] = nlohmann::json::array();
  std::optional<SessionStore> store;
  if (options.flag("save")) {
    auto opened = SessionStore::open(options.get("store"));
    if (!opened) return report_failure(opened.error());
    store.emplace(std::move(*opened));
  }
  for (const auto& t : *testers) {
    nlohmann::json j = {{"tester", t.number},
                        {"vertices", t.rig.vertex_count()},
                        {"triangles", t.rig.triangles.size() / 3},
                        {"blendshapes", t.rig.shape_count()},
                        {"poses", t.poses.size()}};
    if (store) {
      auto subject = store->add_subject("FaceWarehouse Tester_" + std::to_string(t.number));
      if (!subject) return report_failure(subject.error());
      auto rig = store->add_rig(*subject, std::nullopt, t.rig);
      if (!rig) return report_failure(rig.error());
      j["subject"] = *subject;
      j["rig"] = *rig;
      if (!t.poses.empty()) {
        // The poses become the fitted meshes of a session with one capture per pose (no frames).
        std::vector<std::string> guide;
        for (std::size_t i = 0; i < t.poses.size(); ++i)
          guide.push_back("pose_" + std::to_string(i));
        auto session = store->create_session(*subject, guide);
        if (!session) return report_failure(session.error());
        for (std::size_t i = 0; i < t.poses.size(); ++i) {
          auto mesh = store->add_mesh(*session, static_cast<int>(i),
                                      i == 0 ? MeshRole::kNeutral : MeshRole::kFitted, guide[i],
                                      t.poses[i]);
          if (!mesh) return report_failure(mesh.error());
        }
        j["session"] = *session;
      }
    }
    out["testers"].push_back(j);
  }
  std::cout << out.dump(2) << std::endl;
  return kExitOk;
}

// ---------------------------------------------------------------------------------------------
// facebooth store info

int run_store_info(const ParsedOptions& options) {
  StoreOptions ro;
  ro.read_only = true;
  auto store = SessionStore::open(options.get("store"), ro);
  if (!store) return report_failure(store.error());
  nlohmann::json out;
  out["store"] = store->root().string();
  out["schema_version"] = store->schema_version();
  auto subjects = store->subjects();
  auto sessions = store->sessions();
  if (!subjects) return report_failure(subjects.error());
  if (!sessions) return report_failure(sessions.error());
  out["subjects"] = nlohmann::json::array();
  for (const auto& s : *subjects) {
    out["subjects"].push_back({{"id", s.id}, {"name", s.name}, {"created_at", s.created_at}});
  }
  out["sessions"] = nlohmann::json::array();
  for (const auto& s : *sessions) {
    nlohmann::json j = {{"id", s.id},
                        {"subject", s.subject},
                        {"complete", s.complete},
                        {"captures", s.capture_count},
                        {"done", s.done_count},
                        {"created_at", s.created_at}};
    if (!s.origin_booth.empty())  // imported by `sync`: the booth and its session id there
      j["origin"] = {{"booth", s.origin_booth}, {"session", s.origin_session}};
    auto next = store->next_capture(s.id);
    if (next && *next)
      j["next_capture"] = {{"index", (*next)->index}, {"expression", (*next)->expression}};
    out["sessions"].push_back(j);
  }
  if (options.flag("verify")) {
    std::cerr << "store info: checking every data file...\n";
    auto report = store->verify();
    if (!report) return report_failure(report.error());
    out["verify"] = {{"integrity", report->integrity},
                     {"files_checked", report->files_checked},
                     {"problems", report->problems},
                     {"ok", report->ok()}};
  }
  std::cout << out.dump(2) << std::endl;
  return kExitOk;
}

}  // namespace

std::vector<Command> storage_commands() {
  return {
      {{"export",
        "export a subject's blendshapes and fitted meshes (FaceWarehouse, glTF, OBJ, PLY)",
        "Writes a folder with a manifest.json (source, versions, SHA-256 of every file). The "
        "folder appears only when complete (written under a temporary name, then renamed).\n"
        "Layouts: facewarehouse -> Tester_N/Blendshape/shape_0..K.obj + shape.bs, "
        "Tester_N/TrainingPose/pose_i.obj/.png/.land (the ICT FaceKit skin, 11,248 vertices, "
        "mm: not FaceWarehouse's 11,510-vertex mesh or its 46 shapes; see the manifest); glb -> "
        "NAME.glb (neutral + one morph target per blendshape with normals, the face model's "
        "UVs, a PBR material, names in mesh.extras.targetNames, metres); obj/ply -> neutral, "
        "blendshapes/NN_NAME, poses/pose_i (OBJ with vt, vn and face.mtl).\n"
        "--names arkit (the default for glb and --take) gives Apple's 52 ARKit blendshapes in "
        "Apple's order (browInnerUp and cheekPuff combined from their halves, tongueOut a zero "
        "target); --names model (the default for the others) keeps the face model's names.\n"
        "Without a session, --from-face-model --seed N exports a synthetic subject: the face "
        "model with a random identity and 20 poses at known weights.\n"
        "--take ID writes a tracking take as Live Link Face CSV (take_ID.csv) and, when the "
        "take's session has a rig, take_ID.glb: that rig as the glb above with one glTF "
        "animation of the take (the 52 ARKit curves as morph target weights at the take's "
        "frame times, the head pose on a parent node, the Kinect at the origin); with the "
        "session's wrinkle detail (facebooth wrinkles) the mesh is subdivided under it and the "
        "targets carry each shape's detail, so any glTF viewer shows the wrinkles move, and "
        "take_ID_detail_weights.csv + wrinkles/ hold the per-frame map weights and maps. "
        "Without a session or rig the manifest's glb entry says why there is no .glb. "
        "--model ID writes a stored model's file.",
        {{"session", "ID", "export this stored session (its subject's rig and fitted meshes)", ""},
         store_option(),
         {"from-face-model", "", "export a synthetic subject built from the face model", ""},
         {"seed", "N", "identity seed for --from-face-model", "1"},
         {"face-model", "PATH", "face model for --from-face-model (default: the installed one)",
          ""},
         {"take", "ID",
          "export this stored tracking take: Live Link Face CSV, and an animated glb of its "
          "session's rig",
          ""},
         {"model", "ID", "export this stored model (e.g. the bilinear model) file", ""},
         {"format", "NAME", "facewarehouse, glb, obj or ply (for --session/--from-face-model)",
          "facewarehouse"},
         {"out", "DIR", "folder to create", ""},
         {"tester", "N", "FaceWarehouse Tester_N number", "1"},
         {"names", "arkit|model",
          "blendshape names (default: arkit for glb and --take, model for the others)", ""},
         {"force", "", "replace an existing --out folder", ""}}},
       run_export},
      {{"import",
        "read a FaceWarehouse-layout folder (Tester_N/Blendshape, TrainingPose)",
        "Prints what was read. With --save, each tester becomes a subject in the store with its "
        "rig, and its training poses become the fitted meshes of a new session.",
        {{"format", "NAME", "facewarehouse (the only import format)", "facewarehouse"},
         {"in", "DIR", "folder holding Tester_N folders", ""},
         store_option(),
         {"save", "", "store the testers' rigs and poses in --store", ""}}},
       run_import},
      {{"store info",
        "subjects, sessions and resume points of a session store (read-only)",
        "",
        {store_option(),
         {"verify", "", "also run the integrity check and verify every data file's SHA-256", ""},
         {"json", "", "print JSON (the only output format; accepted for symmetry)", ""}}},
       run_store_info},
  };
}

}  // namespace fb::cli
