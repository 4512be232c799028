// Sessions imported from booths (`facebooth sync`): a whole session in one durable step. The
// data files are written first, inside the session's new folder, while one transaction holds the
// rows; the commit (synchronous=FULL) publishes everything at once. A failure rolls the rows
// back and removes the files; a crash leaves files no committed row references, which the next
// writer's open deletes (the orphan cleanup of every commit), so the store is as it was.
#include "storage/session_store_impl.hpp"

namespace fb {

namespace {

bool valid_booth_id(const std::string& id) {
  if (id.empty() || id.size() > 64) return false;
  for (char c : id)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '_') return false;
  return true;
}

Result<void> check_import(const SessionImport& in) {
  if (!valid_booth_id(in.booth))
    return fail("booth id '" + in.booth + "' is not 1..64 characters of [A-Za-z0-9_-]");
  if (in.origin_session <= 0 || in.origin_subject <= 0)
    return fail("an imported session needs its booth session and subject ids");
  if (in.captures.empty()) return fail("an imported session needs at least one capture");
  for (std::size_t i = 0; i < in.captures.size(); ++i) {
    const ImportedCapture& c = in.captures[i];
    const std::string what = "capture " + std::to_string(i) + " (" + c.expression + ")";
    if (c.index != static_cast<int>(i)) return fail(what + " is out of order");
    if (c.state == CaptureState::kDone && c.frames.empty())
      return fail(what + " is done but has no frame");
    if (c.mesh) {
      const MeshData& m = *c.mesh;
      if (m.positions.empty() || m.positions.size() % 3 != 0 || m.triangles.size() % 3 != 0)
        return fail(what + ": its mesh is malformed");
      for (auto t : m.triangles)
        if (t >= static_cast<std::uint32_t>(m.vertex_count()))
          return fail(what + ": its mesh has a triangle index past its vertex count");
    }
  }
  return success();
}

std::vector<std::uint8_t> depth_file(const DepthImage& depth) {
  ByteWriter w;
  w.put_magic(kDepthMagic);
  w.put(static_cast<std::int32_t>(depth.width));
  w.put(static_cast<std::int32_t>(depth.height));
  w.put_span(std::span<const std::uint16_t>(depth.pixels));
  return std::move(w.bytes);
}

std::vector<std::uint8_t> mesh_file(const MeshData& mesh) {
  ByteWriter w;
  w.put_magic(kMeshMagic);
  w.put(static_cast<std::uint32_t>(mesh.vertex_count()));
  w.put(static_cast<std::uint32_t>(mesh.triangle_count()));
  w.put_span(std::span<const float>(mesh.positions));
  w.put_span(std::span<const std::uint32_t>(mesh.triangles));
  return std::move(w.bytes);
}

// The subject the booth's subject maps to: found by origin, else added (folder included).
Result<SubjectId> imported_subject(const SessionStore::Impl& impl, const SessionImport& in) {
  sqlite3* db = impl.db.get();
  auto find = sql::prepare(db, "SELECT id FROM subjects WHERE origin_booth=? AND origin_id=?");
  if (!find) return find.failure();
  find->bind_all(in.booth, in.origin_subject);
  auto row = find->step();
  if (!row) return row.failure();
  if (*row) return find->int64(0);
  auto add = sql::prepare(db, "INSERT INTO subjects(name, origin_booth, origin_id) VALUES(?,?,?)");
  if (!add) return add.failure();
  add->bind_all(in.subject_name, in.booth, in.origin_subject);
  if (auto r = add->run(); !r) return r.failure();
  const SubjectId id = sqlite3_last_insert_rowid(db);
  std::error_code ec;
  const fs::path folder = impl.root / "subjects" / std::to_string(id);
  fs::create_directories(folder, ec);
  if (ec) return fail("cannot create " + folder.string() + ": " + ec.message());
  if (auto r = fsync_directory(folder.parent_path()); !r) return r.failure();
  return id;
}

// One capture's files and rows, inside the import's transaction; `written` collects the files.
Result<void> import_capture(const SessionStore::Impl& impl, SessionId session,
                            const std::string& folder, const ImportedCapture& c,
                            std::vector<SessionStore::Impl::StoredFile>& written) {
  sqlite3* db = impl.db.get();
  auto insert = sql::prepare(db,
                             "INSERT INTO captures(session_id, idx, expression, state, attempts, "
                             "qa_json) VALUES(?,?,?,?,?,?)");
  if (!insert) return insert.failure();
  const bool done = c.state == CaptureState::kDone;
  // The rows of a done capture are inserted pending and then finished like commit_capture does,
  // so the table's check (done needs a frames file) holds at every statement.
  insert->bind_all(session, c.index, c.expression, done ? "pending" : to_string(c.state),
                   c.attempts, scores_to_json(c.qa_scores));
  if (auto r = insert->run(); !r) return r.failure();
  const std::int64_t capture_id = sqlite3_last_insert_rowid(db);
  if (!done) return success();

  const std::string stem = "c" + std::to_string(c.index) + "-import";
  CaptureInput frames;
  frames.frames = c.frames;
  auto sequence = write_frame_sequence(impl, folder, stem, frames, c.frames.size());
  if (!sequence) return sequence.failure();
  written.push_back(sequence->file);
  auto frames_file = impl.insert_file_row(sequence->file);
  if (!frames_file) return frames_file.failure();
  std::optional<std::int64_t> fused_file;
  if (!c.fused_depth.empty()) {
    auto f = impl.write_data_file(folder, stem + "-fused.fbdep", depth_file(c.fused_depth));
    if (!f) return f.failure();
    written.push_back(*f);
    auto id = impl.insert_file_row(*f);
    if (!id) return id.failure();
    fused_file = *id;
  }
  auto frame = sql::prepare(db,
                            "INSERT INTO frames(capture_id, seq, depth_host_time_s, "
                            "color_host_time_s, depth_device_ts, color_device_ts, file_id, offset) "
                            "VALUES(?,?,?,?,?,?,?,?)");
  if (!frame) return frame.failure();
  for (std::size_t i = 0; i < c.frames.size(); ++i) {
    const frame_record::Header& h = sequence->headers[i];
    frame->reset();
    frame->bind_all(capture_id, static_cast<std::int64_t>(i), h.depth_host_time_s,
                    h.color_host_time_s, static_cast<std::int64_t>(h.depth_device_timestamp),
                    static_cast<std::int64_t>(h.color_device_timestamp), *frames_file,
                    static_cast<std::int64_t>(sequence->offsets[i]));
    if (auto r = frame->run(); !r) return r;
  }
  if (!c.landmarks.empty()) {
    auto lm =
        sql::prepare(db, "INSERT INTO landmarks(capture_id, source, points_json) VALUES(?,?,?)");
    if (!lm) return lm.failure();
    lm->bind_all(capture_id,
                 c.landmark_source == LandmarkSource::kOperator ? "operator" : "automatic",
                 landmarks_to_json(c.landmarks));
    if (auto r = lm->run(); !r) return r;
  }
  auto finish = sql::prepare(db, std::string("UPDATE captures SET state='done', frame_count=?, "
                                             "frames_file_id=?, fused_file_id=?, completed_at=") +
                                     kNow + " WHERE id=?");
  if (!finish) return finish.failure();
  finish->bind_all(static_cast<std::int64_t>(c.frames.size()), *frames_file, fused_file,
                   capture_id);
  if (auto r = finish->run(); !r) return r;
  if (c.mesh) {
    auto f = impl.write_data_file(folder, "mesh.fbmsh", mesh_file(*c.mesh));
    if (!f) return f.failure();
    written.push_back(*f);
    auto id = impl.insert_file_row(*f);
    if (!id) return id.failure();
    auto mesh = sql::prepare(db,
                             "INSERT INTO meshes(session_id, capture_idx, role, name, "
                             "vertex_count, triangle_count, file_id) VALUES(?,?,?,?,?,?,?)");
    if (!mesh) return mesh.failure();
    mesh->bind_all(session, c.index, to_string(c.mesh_role), c.expression, c.mesh->vertex_count(),
                   c.mesh->triangle_count(), *id);
    if (auto r = mesh->run(); !r) return r;
  }
  return success();
}

}  // namespace

Result<std::optional<SessionId>> SessionStore::imported_session(const std::string& booth,
                                                                std::int64_t origin_session) const {
  if (impl_->schema_version < 5) return std::optional<SessionId>{};
  auto stmt =
      sql::prepare(impl_->db.get(), "SELECT id FROM sessions WHERE origin_booth=? AND origin_id=?");
  if (!stmt) return stmt.failure();
  stmt->bind_all(booth, origin_session);
  auto row = stmt->step();
  if (!row) return row.failure();
  if (!*row) return std::optional<SessionId>{};
  return std::optional<SessionId>(stmt->int64(0));
}

Result<SessionId> SessionStore::import_session(const SessionImport& in) {
  if (auto r = impl_->require_writer(); !r) return r.failure();
  if (auto r = check_import(in); !r) return r.failure();
  const std::string what = "session " + std::to_string(in.origin_session) + " of booth " + in.booth;
  auto before = imported_session(in.booth, in.origin_session);
  if (!before) return before.failure();
  if (*before)
    return fail(what + " is already in this store as session " + std::to_string(**before) +
                "; nothing was changed");
  sqlite3* db = impl_->db.get();
  std::vector<Impl::StoredFile> written;
  auto import = [&]() -> Result<SessionId> {
    if (auto r = sql::exec(db, "PRAGMA synchronous=FULL"); !r) return r.failure();
    auto tx = sql::Transaction::begin(db);
    if (!tx) return tx.failure();
    auto subject = imported_subject(*impl_, in);
    if (!subject) return subject.failure();
    auto stmt = sql::prepare(db,
                             "INSERT INTO sessions(subject_id, folder, calibration_json, "
                             "origin_booth, origin_id) VALUES(?, '', ?, ?, ?)");
    if (!stmt) return stmt.failure();
    stmt->bind_all(*subject,
                   in.calibration_json.empty() ? std::nullopt
                                               : std::optional<std::string>(in.calibration_json),
                   in.booth, in.origin_session);
    if (auto r = stmt->run(); !r) return r.failure();
    const SessionId id = sqlite3_last_insert_rowid(db);
    auto recorded = impl_->record_session_folder(id);
    if (!recorded) return recorded.failure();
    const std::string folder = *recorded;
    std::error_code ec;
    fs::create_directories(impl_->root / folder, ec);
    if (ec) return fail("cannot create " + (impl_->root / folder).string() + ": " + ec.message());
    if (auto r = fsync_directory(impl_->root / "sessions"); !r) return r.failure();
    for (const ImportedCapture& c : in.captures)
      if (auto r = import_capture(*impl_, id, folder, c, written); !r) return r.failure();
    auto complete = sql::prepare(db,
                                 "UPDATE sessions SET state='complete' WHERE id=?1 AND NOT EXISTS "
                                 "(SELECT 1 FROM captures WHERE session_id=?1 AND state<>'done')");
    if (!complete) return complete.failure();
    complete->bind(1, id);
    if (auto r = complete->run(); !r) return r.failure();
    impl_->phase(StorePhase::kCommitting);
    if (auto r = tx->commit(); !r) return r.failure();
    return id;
  };
  auto imported = import();
  (void)sql::exec(db, "PRAGMA synchronous=NORMAL");
  impl_->phase(StorePhase::kIdle);
  if (!imported) {
    impl_->discard(written);
    return fail(what + " was not imported (nothing was stored): " + imported.error().message);
  }
  return imported;
}

}  // namespace fb
