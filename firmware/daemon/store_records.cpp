// SessionRecords over the SQLite SessionStore (storage/session_store.hpp): the production
// store, with crash-safe commits of every frame, the fused depth and the QA scores.
#include <algorithm>
#include <nlohmann/json.hpp>
#include <set>

#include "firmware/daemon/session_records.hpp"
#include "storage/export/export_folder.hpp"
#include "storage/export/export_session.hpp"
#include "storage/export/mesh_files.hpp"
#include "storage/export/png_file.hpp"
#include "storage/session_store.hpp"

namespace fb {
namespace fs = std::filesystem;

namespace {

RecordState from_store(CaptureState s) {
  switch (s) {
    case CaptureState::kPending:
      return RecordState::kPending;
    case CaptureState::kCapturing:
      return RecordState::kCapturing;
    case CaptureState::kRejected:
      return RecordState::kRejected;
    case CaptureState::kDone:
      return RecordState::kDone;
  }
  return RecordState::kPending;
}

class StoreRecords : public SessionRecords {
 public:
  explicit StoreRecords(SessionStore store) : store_(std::move(store)) {}

  std::string backend() const override { return "sqlite"; }
  fs::path root() const override { return store_.root(); }

  Result<std::int64_t> add_subject(const std::string& name) override {
    return store_.add_subject(name);
  }
  Result<std::int64_t> create_session(std::int64_t subject,
                                      const std::vector<std::string>& guide) override {
    return store_.create_session(subject, guide);
  }
  Result<std::vector<RecordSession>> sessions() override {
    auto all = store_.sessions();
    if (!all) return all.failure();
    std::vector<RecordSession> out;
    for (const auto& s : *all) out.push_back(convert(s));
    std::sort(out.begin(), out.end(), [](auto& a, auto& b) { return a.id < b.id; });
    return out;
  }
  Result<RecordSession> session(std::int64_t id) override {
    auto s = store_.session(id);
    if (!s) return s.failure();
    return convert(*s);
  }
  Result<std::vector<RecordCapture>> captures(std::int64_t session) override {
    auto all = store_.captures(session);
    if (!all) return all.failure();
    std::vector<RecordCapture> out;
    for (const auto& c : *all) {
      RecordCapture rc;
      rc.index = c.index;
      rc.expression = c.expression;
      rc.state = from_store(c.state);
      rc.attempts = c.attempts;
      rc.qa_scores = c.qa_scores;
      rc.frame_count = c.frame_count;
      rc.completed_at = c.completed_at;
      out.push_back(std::move(rc));
    }
    return out;
  }
  Result<void> begin_capture(std::int64_t session, int index) override {
    return store_.begin_capture(session, index);
  }
  Result<void> reject_capture(std::int64_t session, int index,
                              const std::map<std::string, double>& qa) override {
    return store_.reject_capture(session, index, qa);
  }
  Result<void> commit_capture(std::int64_t session, int index, CaptureCommit commit) override;
  Result<fs::path> export_session(std::int64_t id, const fs::path& exports_dir,
                                  const std::function<bool()>& cancelled) override;

  bool keeps_fits() const override { return true; }
  Result<void> add_fit(std::int64_t session, int index, const FitRecord& fit) override {
    auto id = store_.add_mesh(session, index, fit.neutral ? MeshRole::kNeutral : MeshRole::kFitted,
                              fit.name, fit.mesh);
    if (!id) return id.failure();
    return success();
  }
  Result<std::optional<MeshData>> neutral_mesh(std::int64_t session) override {
    auto all = store_.meshes(session);
    if (!all) return all.failure();
    std::optional<MeshId> newest;
    for (const auto& m : *all)
      if (m.role == MeshRole::kNeutral) newest = m.id;  // listed oldest first
    if (!newest) return std::optional<MeshData>{};
    auto mesh = store_.read_mesh(*newest);
    if (!mesh) return mesh.failure();
    return std::optional<MeshData>(std::move(*mesh));
  }
  Result<void> set_operator_landmarks(std::int64_t session, int index,
                                      const std::vector<Landmark>& landmarks) override {
    return store_.set_operator_landmarks(session, index, landmarks);
  }
  Result<std::int64_t> add_take(const TakeRecord& take, TakeWriter& frames) override {
    if (take.session > 0) {
      auto s = store_.session(take.session);
      if (!s) return s.failure();
      return frames.store(store_, s->subject, take.session);
    }
    auto subject = store_.add_subject(take.subject_name.empty() ? "tracking" : take.subject_name);
    if (!subject) return subject.failure();
    return frames.store(store_, *subject, std::nullopt);
  }
  Result<OffloadInfo> offload_info(std::int64_t session) override {
    OffloadInfo info;
    auto s = store_.session(session);
    if (!s) return s.failure();
    auto meshes = store_.meshes(session);
    if (!meshes) return meshes.failure();
    std::set<int> fitted;
    for (const auto& m : *meshes)
      if (m.capture_index && m.role != MeshRole::kScan) fitted.insert(*m.capture_index);
    info.fitted_captures = static_cast<int>(fitted.size());
    auto rigs = store_.rigs(s->subject);
    if (!rigs) return rigs.failure();
    for (const auto& r : *rigs) {  // newest first
      if (r.session != session) continue;
      if (info.rigs++ == 0) info.rig_detail_captures = r.detail_captures;
    }
    return info;
  }
  Result<std::int64_t> add_rig(std::int64_t session, const RigData& rig) override {
    auto s = store_.session(session);
    if (!s) return s.failure();
    return store_.add_rig(s->subject, session, rig);
  }
  Result<std::optional<StoredRig>> rig_for(std::int64_t session) override {
    auto serving = store_.rig_for(session);
    if (!serving) return serving.failure();
    if (!*serving) return std::optional<StoredRig>{};
    StoredRig out;
    out.id = (*serving)->id;
    out.subject = (*serving)->subject;
    auto data = store_.read_rig(out.id);
    if (!data) return data.failure();
    out.data = std::move(*data);
    return std::optional<StoredRig>(std::move(out));
  }

 private:
  RecordSession convert(const SessionInfo& s) {
    RecordSession r;
    r.id = s.id;
    r.subject = s.subject;
    if (auto subj = store_.subject(s.subject)) r.subject_name = subj->name;
    r.created_at = s.created_at;
    r.complete = s.complete;
    r.capture_count = s.capture_count;
    r.done_count = s.done_count;
    r.folder = s.folder;
    return r;
  }

  Result<bool> export_capture(ExportFolder& folder, std::int64_t id, const CaptureInfo& c,
                              const std::vector<MeshInfo>& meshes, nlohmann::json& j);
  Result<void> finish_bundle(ExportFolder& folder, const SessionInfo& s, std::size_t captures,
                             int fitted, nlohmann::json list);

  SessionStore store_;
};

Result<void> StoreRecords::commit_capture(std::int64_t session, int index, CaptureCommit commit) {
  CaptureInput input;
  if (!commit.frames) return fail("capture " + std::to_string(index) + " has no frames");
  input.frame_count = commit.frames->size();
  input.read_frame = [&](std::size_t i, RgbdFrame& out) { return commit.frames->read(i, out); };
  input.fused_depth = std::move(commit.fused_depth);
  input.qa_scores = std::move(commit.qa_scores);
  input.landmarks = std::move(commit.landmarks);
  // The host maps these frames' depth to colour (texture, refit) with the unit's calibration.
  if (!commit.calibration_json.empty())
    if (auto r = store_.set_session_calibration(session, commit.calibration_json); !r) return r;
  return store_.commit_capture(session, index, input);
}

// The capture's landmarks as the bundle's landmarks.json.
nlohmann::json landmarks_doc(const CaptureData& data) {
  nlohmann::json pts = nlohmann::json::array();
  for (const auto& l : data.landmarks) {
    nlohmann::json p = {{"u", l.u}, {"v", l.v}};
    if (l.has_3d) p["xyz_mm"] = {l.x, l.y, l.z};
    pts.push_back(p);
  }
  return {{"source", data.landmark_source == LandmarkSource::kOperator ? "operator" : "automatic"},
          {"order", "iBUG 68"},
          {"units", "colour image px; xyz in the depth camera frame, mm"},
          {"points", pts}};
}

// One done capture's files in the bundle, named in its entry `j`: the fused depth, the colour
// of frame 0 and the landmarks, then the newest fitted mesh. True when it had a mesh.
Result<bool> StoreRecords::export_capture(ExportFolder& folder, std::int64_t id,
                                          const CaptureInfo& c, const std::vector<MeshInfo>& meshes,
                                          nlohmann::json& j) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "capture-%02d-%s/", c.index, c.expression.c_str());
  const std::string dir = buf;
  {
    // Scoped: the frames are released before the mesh is read.
    auto data = store_.read_capture(id, c.index, {.max_frames = 1});  // colour of frame 0
    if (!data) return data.failure();
    if (!data->fused_depth.empty()) {
      if (auto ok = folder.write_text(dir + "fused_depth.pgm", encode_pgm16(data->fused_depth));
          !ok)
        return ok.failure();
      j["fused_depth"] = dir + "fused_depth.pgm";
    }
    if (!data->frames.empty() && !data->frames.front().color.empty()) {
      auto png = encode_png(data->frames.front().color);
      if (!png) return png.failure();
      if (auto ok = folder.write_file(dir + "color.png", *png); !ok) return ok.failure();
      j["color"] = dir + "color.png";
    }
    if (!data->landmarks.empty()) {
      if (auto ok = folder.write_text(dir + "landmarks.json", landmarks_doc(*data).dump(1)); !ok)
        return ok.failure();
      j["landmarks"] = dir + "landmarks.json";
    }
  }
  const MeshInfo* newest = nullptr;
  for (const auto& m : meshes)
    if (m.capture_index == c.index && m.role != MeshRole::kScan) newest = &m;
  if (!newest) return false;
  auto mesh = store_.read_mesh(newest->id);
  if (!mesh) return mesh.failure();
  if (auto ok = folder.write_text(
          dir + "mesh.obj",
          encode_obj(*mesh, "quick fit of " + c.expression + ", model frame, mm"));
      !ok)
    return ok.failure();
  j["mesh"] = dir + "mesh.obj";
  j["mesh_role"] = to_string(newest->role);
  return true;
}

// session.json and the unit's calibration, then the manifest (which renames the folder).
Result<void> StoreRecords::finish_bundle(ExportFolder& folder, const SessionInfo& s,
                                         std::size_t captures, int fitted, nlohmann::json list) {
  std::string subject_name;
  if (auto subj = store_.subject(s.subject)) subject_name = subj->name;
  nlohmann::json session_doc = {{"format", "facebooth-session-bundle"},
                                {"version", 3},
                                {"session", s.id},
                                {"subject", subject_name},
                                {"subject_id", s.subject},
                                {"created_at", s.created_at},
                                {"complete", s.complete},
                                {"fitted_captures", fitted},
                                {"captures", std::move(list)}};
  // v3: the unit's calibration, which the host needs to map depth to colour when it refits.
  if (!s.calibration_json.empty()) {
    if (auto ok = folder.write_text("calibration.json", s.calibration_json); !ok)
      return ok.failure();
    session_doc["calibration"] = "calibration.json";
  }
  if (auto ok = folder.write_text("session.json", session_doc.dump(1)); !ok) return ok.failure();
  ExportManifest manifest;
  manifest.what = "facebooth-session-bundle";
  manifest.source = {{"kind", "session"},
                     {"store", store_.root().string()},
                     {"session", std::to_string(s.id)},
                     {"subject", std::to_string(s.subject)}};
  manifest.details = {{"captures", std::to_string(captures)},
                      {"fitted_captures", std::to_string(fitted)},
                      {"units", "mm; meshes in the face model frame"}};
  return folder.finish(manifest);
}

// The session bundle the host fetches (offload) and the kiosk's export: assembled with
// storage/export's ExportFolder (temporary folder, SHA-256 manifest, atomic rename). Per done
// capture: the fused depth (16-bit PGM, mm), the frontal colour frame (PNG), its landmarks
// (JSON, the operator's correction when there is one) and the newest fitted mesh (OBJ, model
// frame, mm); per session the unit's calibration (device.json). The host's `facebooth sync`
// reads it (storage/bundle_import.hpp). When the subject has a rig from this session, a
// FaceWarehouse folder is added through storage/export's session exporter.
Result<fs::path> StoreRecords::export_session(std::int64_t id, const fs::path& exports_dir,
                                              const std::function<bool()>& cancelled) {
  auto stop_requested = [&]() -> Result<void> {
    if (cancelled && cancelled())
      return fail("the export of session " + std::to_string(id) +
                  " was abandoned because the daemon is stopping; the session is stored, export "
                  "it again with POST /api/sessions/" +
                  std::to_string(id) + "/export");
    return success();
  };
  auto s = store_.session(id);
  if (!s) return s.failure();
  auto caps = store_.captures(id);
  if (!caps) return caps.failure();
  auto meshes = store_.meshes(id);
  if (!meshes) return meshes.failure();
  const fs::path out = exports_dir / ("session-" + std::to_string(id));
  std::error_code ec;
  fs::create_directories(exports_dir, ec);
  if (ec) return fail("cannot create '" + exports_dir.string() + "': " + ec.message());
  auto folder = ExportFolder::create(out, /*overwrite=*/true);
  if (!folder) return folder.failure();
  nlohmann::json list = nlohmann::json::array();
  int fitted = 0;
  for (const auto& c : *caps) {
    if (auto ok = stop_requested(); !ok) return ok.failure();
    nlohmann::json j = {{"index", c.index},
                        {"expression", c.expression},
                        {"state", to_string(from_store(c.state))},
                        {"attempts", c.attempts},
                        {"qa", c.qa_scores},
                        {"frame_count", c.frame_count}};
    if (c.state == CaptureState::kDone) {
      auto had_mesh = export_capture(*folder, id, c, *meshes, j);
      if (!had_mesh) return had_mesh.failure();
      fitted += *had_mesh;
    }
    list.push_back(std::move(j));
  }
  if (auto ok = finish_bundle(*folder, *s, caps->size(), fitted, std::move(list)); !ok)
    return ok.failure();

  // With a rig from the host built from this session: the FaceWarehouse layout next to the
  // bundle.
  auto serving = store_.rig_for(id);
  if (serving && *serving && (*serving)->session == id) {
    if (auto ok = stop_requested(); !ok) return ok.failure();
    auto content = load_session_content(store_, id);
    if (!content) return content.failure();
    ExportRequest request;
    request.format = ExportFormat::kFaceWarehouse;
    request.out = exports_dir / ("session-" + std::to_string(id) + "-facewarehouse");
    request.overwrite = true;
    if (auto ok = export_content(*content, request); !ok) return ok.failure();
  }
  return out;
}
}  // namespace

Result<std::unique_ptr<SessionRecords>> open_session_records(const fs::path& data_dir) {
  auto store = SessionStore::open(data_dir / "store");
  if (!store) return store.failure();
  return std::unique_ptr<SessionRecords>(std::make_unique<StoreRecords>(std::move(*store)));
}

}  // namespace fb
