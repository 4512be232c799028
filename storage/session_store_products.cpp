// The session store's products: fitted meshes, rigs (and which one serves a session), models and
// tracking takes.
#include "storage/session_store_impl.hpp"

namespace fb {

namespace {

Result<void> check_mesh(const MeshData& mesh, const std::string& what) {
  if (mesh.positions.empty() || mesh.positions.size() % 3 != 0) {
    return fail(what + " has no vertices or a position count that is not a multiple of 3");
  }
  if (mesh.triangles.size() % 3 != 0) return fail(what + " has a partial triangle");
  const auto n = static_cast<std::uint32_t>(mesh.vertex_count());
  for (auto t : mesh.triangles) {
    if (t >= n) return fail(what + " has a triangle index past its vertex count");
  }
  return success();
}

}  // namespace

Result<MeshId> SessionStore::add_mesh(SessionId session, std::optional<int> capture_index,
                                      MeshRole role, const std::string& name,
                                      const MeshData& mesh) {
  auto ids = add_meshes(session, {MeshInput{capture_index, role, name, mesh}});
  if (!ids) return ids.failure();
  return ids->front();
}

Result<std::vector<MeshId>> SessionStore::add_meshes(SessionId session,
                                                     const std::vector<MeshInput>& meshes) {
  if (auto r = impl_->require_writer(); !r) return r.failure();
  if (meshes.empty()) return fail("no meshes to add");
  for (const auto& m : meshes)
    if (auto r = check_mesh(m.mesh, "mesh '" + m.name + "'"); !r) return r.failure();
  auto folder = impl_->session_folder(session);
  if (!folder) return folder.failure();
  std::vector<Impl::StoredFile> files;
  for (const auto& m : meshes) {
    ByteWriter w;
    w.put_magic(kMeshMagic);
    w.put(static_cast<std::uint32_t>(m.mesh.vertex_count()));
    w.put(static_cast<std::uint32_t>(m.mesh.triangle_count()));
    w.put_span(std::span<const float>(m.mesh.positions));
    w.put_span(std::span<const std::uint32_t>(m.mesh.triangles));
    auto file = impl_->write_data_file(*folder, "mesh.fbmsh", w.bytes);
    if (!file) {
      impl_->discard(files);
      return file.failure();
    }
    files.push_back(std::move(*file));
  }
  sqlite3* db = impl_->db.get();
  // Every file is durable before the one commit: a crash leaves all of the meshes or none.
  auto insert = [&]() -> Result<std::vector<MeshId>> {
    auto tx = sql::Transaction::begin(db);
    if (!tx) return tx.failure();
    std::vector<MeshId> ids;
    for (std::size_t k = 0; k < meshes.size(); ++k) {
      const MeshInput& m = meshes[k];
      auto id = impl_->insert_file_row(files[k]);
      if (!id) return id.failure();
      auto stmt = sql::prepare(db,
                               "INSERT INTO meshes(session_id, capture_idx, role, name, "
                               "vertex_count, triangle_count, file_id) VALUES(?,?,?,?,?,?,?)");
      if (!stmt) return stmt.failure();
      stmt->bind_all(
          session, m.capture_index ? std::optional<std::int64_t>(*m.capture_index) : std::nullopt,
          to_string(m.role), m.name, m.mesh.vertex_count(), m.mesh.triangle_count(), *id);
      if (auto r = stmt->run(); !r) return r.failure();
      ids.push_back(sqlite3_last_insert_rowid(db));
    }
    if (auto r = tx->commit(); !r) return r.failure();
    return ids;
  };
  auto ids = insert();
  if (!ids) impl_->discard(files);
  return ids;
}

Result<std::vector<MeshInfo>> SessionStore::meshes(SessionId session) const {
  return impl_->rows<MeshInfo>(
      "SELECT id, session_id, capture_idx, role, name, vertex_count, triangle_count FROM meshes "
      "WHERE session_id=? ORDER BY id",
      session, [](sql::Statement& stmt) {
        MeshInfo m;
        m.id = stmt.int64(0);
        m.session = stmt.int64(1);
        if (!stmt.is_null(2)) m.capture_index = stmt.int32(2);
        m.role = mesh_role_from(stmt.text(3));
        m.name = stmt.text(4);
        m.vertex_count = stmt.int32(5);
        m.triangle_count = stmt.int32(6);
        return m;
      });
}

Result<MeshData> SessionStore::read_mesh(MeshId id) const {
  auto stmt = sql::prepare(impl_->db.get(), "SELECT file_id FROM meshes WHERE id=?");
  if (!stmt) return stmt.failure();
  stmt->bind(1, id);
  auto row = stmt->step();
  if (!row) return row.failure();
  if (!*row) return fail("there is no mesh " + std::to_string(id) + " in this store");
  auto bytes = impl_->load_file(stmt->int64(0));
  if (!bytes) return bytes.failure();
  MeshData mesh;
  if (!decode_mesh(*bytes, mesh)) {
    return fail("the file of mesh " + std::to_string(id) + " is malformed");
  }
  return mesh;
}

Result<RigId> SessionStore::add_rig(SubjectId subject, std::optional<SessionId> session,
                                    const RigData& rig) {
  if (auto r = impl_->require_writer(); !r) return r.failure();
  if (auto r = check_mesh(rig.neutral_mesh(), "the rig's neutral"); !r) return r.failure();
  if (rig.shape_names.size() != rig.shapes.size()) {
    return fail("the rig has " + std::to_string(rig.shapes.size()) + " shapes but " +
                std::to_string(rig.shape_names.size()) + " names");
  }
  for (const auto& s : rig.shapes) {
    if (s.size() != rig.neutral.size()) return fail("a rig shape differs in vertex count");
  }
  for (std::size_t i = 0; i < rig.detail_captures.size(); ++i) {
    const auto& c = rig.detail_captures[i];
    if (c.capture_index < 0 || c.expression.empty())
      return fail("a rig's detail capture needs a capture index >= 0 and its expression");
    for (std::size_t k = 0; k < i; ++k)
      if (rig.detail_captures[k].capture_index == c.capture_index)
        return fail("the rig lists capture " + std::to_string(c.capture_index) +
                    " twice among its detail captures");
  }
  // Before schema v7 (a store opened with an older migrate_to) only a rig without detail fits.
  if (!rig.detail_captures.empty() && impl_->schema_version < 7)
    return fail("this store's schema v" + std::to_string(impl_->schema_version) +
                " cannot keep a rig's detail captures; open it as the writer to migrate it");
  if (auto r = impl_->ensure_subject(subject); !r) return r.failure();
  ByteWriter w;
  w.put_magic(kRigMagic);
  w.put(static_cast<std::uint32_t>(rig.vertex_count()));
  w.put(static_cast<std::uint32_t>(rig.triangles.size() / 3));
  w.put(static_cast<std::uint32_t>(rig.shapes.size()));
  w.put_span(std::span<const float>(rig.neutral));
  for (const auto& s : rig.shapes) w.put_span(std::span<const float>(s));
  w.put_span(std::span<const std::uint32_t>(rig.triangles));
  const std::string folder = "subjects/" + std::to_string(subject);
  auto file = impl_->write_data_file(folder, "rig.fbrig", w.bytes);
  if (!file) return file.failure();
  if (rig.detail_captures.empty())
    return impl_->insert_with_files(
        {*file},
        "INSERT INTO rigs(subject_id, session_id, shape_names_json, "
        "vertex_count, triangle_count, file_id) VALUES(?,?,?,?,?,?)",
        [&](sql::Statement& stmt, const std::vector<std::int64_t>& ids) {
          stmt.bind_all(subject, session, names_to_json(rig.shape_names), rig.vertex_count(),
                        static_cast<int>(rig.triangles.size() / 3), ids[0]);
        });
  return impl_->insert_with_files(
      {*file},
      "INSERT INTO rigs(subject_id, session_id, shape_names_json, "
      "vertex_count, triangle_count, file_id, detail_json) VALUES(?,?,?,?,?,?,?)",
      [&](sql::Statement& stmt, const std::vector<std::int64_t>& ids) {
        stmt.bind_all(subject, session, names_to_json(rig.shape_names), rig.vertex_count(),
                      static_cast<int>(rig.triangles.size() / 3), ids[0],
                      detail_captures_to_json(rig.detail_captures));
      });
}

Result<std::vector<RigInfo>> SessionStore::rigs(SubjectId subject) const {
  // detail_json is schema v7's; an older store (migrate_to) lists no detail.
  const std::string detail = impl_->schema_version >= 7 ? "detail_json" : "'[]'";
  return impl_->rows<RigInfo>(
      "SELECT id, subject_id, session_id, shape_names_json, vertex_count, triangle_count, "
      "created_at, " +
          detail + " FROM rigs WHERE subject_id=? ORDER BY id DESC",
      subject, [](sql::Statement& stmt) {
        RigInfo info;
        info.id = stmt.int64(0);
        info.subject = stmt.int64(1);
        info.session = stmt.optional_int64(2);
        info.shape_names = names_from_json(stmt.text(3));
        info.vertex_count = stmt.int32(4);
        info.triangle_count = stmt.int32(5);
        info.created_at = stmt.text(6);
        info.detail_captures = detail_captures_from_json(stmt.text(7));
        return info;
      });
}

Result<std::optional<RigInfo>> SessionStore::newest_rig(SubjectId subject) const {
  auto all = rigs(subject);
  if (!all) return all.failure();
  if (all->empty()) return std::optional<RigInfo>{};
  return std::optional<RigInfo>(std::move(all->front()));  // listed newest first
}

Result<std::optional<RigInfo>> SessionStore::rig_for(SessionId session) const {
  auto info = this->session(session);
  if (!info) return info.failure();
  auto all = rigs(info->subject);
  if (!all) return all.failure();
  for (auto& r : *all)  // newest first
    if (r.session == session) return std::optional<RigInfo>(std::move(r));
  if (all->empty()) return std::optional<RigInfo>{};
  return std::optional<RigInfo>(std::move(all->front()));
}

Result<RigData> SessionStore::read_rig(RigId id, bool verify_sha256) const {
  auto stmt = sql::prepare(
      impl_->db.get(), impl_->schema_version >= 7
                           ? "SELECT file_id, shape_names_json, detail_json FROM rigs WHERE id=?"
                           : "SELECT file_id, shape_names_json, '[]' FROM rigs WHERE id=?");
  if (!stmt) return stmt.failure();
  stmt->bind(1, id);
  auto row = stmt->step();
  if (!row) return row.failure();
  if (!*row) return fail("there is no rig " + std::to_string(id) + " in this store");
  RigData rig;
  rig.shape_names = names_from_json(stmt->text(1));
  rig.detail_captures = detail_captures_from_json(stmt->text(2));
  auto bytes = impl_->load_file(stmt->int64(0), verify_sha256);
  if (!bytes) return bytes.failure();
  if (!decode_rig(*bytes, rig))
    return fail("the file of rig " + std::to_string(id) + " is malformed");
  return rig;
}

Result<ModelId> SessionStore::add_model(const std::string& kind, const std::string& params_json,
                                        std::span<const std::uint8_t> bytes) {
  if (auto r = impl_->require_writer(); !r) return r.failure();
  auto file = impl_->write_data_file("models", kind + ".bin", bytes);
  if (!file) return file.failure();
  return impl_->insert_with_files({*file},
                                  "INSERT INTO models(kind, params_json, file_id) VALUES(?,?,?)",
                                  [&](sql::Statement& stmt, const std::vector<std::int64_t>& ids) {
                                    stmt.bind_all(kind, params_json, ids[0]);
                                  });
}

Result<std::vector<ModelInfo>> SessionStore::models() const {
  return impl_->rows<ModelInfo>(
      "SELECT m.id, m.kind, m.params_json, f.bytes, m.created_at FROM models m JOIN files f ON "
      "f.id=m.file_id ORDER BY m.id",
      std::nullopt, [](sql::Statement& stmt) {
        return ModelInfo{stmt.int64(0), stmt.text(1), stmt.text(2), stmt.int64(3), stmt.text(4)};
      });
}

Result<std::vector<std::uint8_t>> SessionStore::read_model(ModelId id) const {
  auto file =
      sql::query_int(impl_->db.get(), "SELECT file_id FROM models WHERE id=" + std::to_string(id));
  if (!file) return file.failure();
  if (*file == 0) return fail("there is no model " + std::to_string(id) + " in this store");
  return impl_->load_file(*file);
}

Result<TakeId> SessionStore::add_take(const TakeData& take) {
  const TakeInfo& info = take.info;
  if (auto r = impl_->require_writer(); !r) return r.failure();
  if (info.fps <= 0) return fail("a take needs a positive frame rate");
  const auto frames = static_cast<std::size_t>(std::max(info.frame_count, 0));
  if (take.values.size() != frames * static_cast<std::size_t>(info.stride()) ||
      take.times_s.size() != frames) {
    return fail("a take of " + std::to_string(info.frame_count) + " frames and " +
                std::to_string(info.shape_names.size()) + " shapes needs " +
                std::to_string(frames * static_cast<std::size_t>(info.stride())) + " values and " +
                std::to_string(frames) + " times, got " + std::to_string(take.values.size()) +
                " and " + std::to_string(take.times_s.size()));
  }
  if (auto r = impl_->ensure_subject(info.subject); !r) return r.failure();
  ByteWriter w;
  w.bytes.reserve(16 + take.times_s.size() * sizeof(double) + take.values.size() * sizeof(float));
  w.put_magic(kTakeMagic);
  w.put(static_cast<std::uint32_t>(info.frame_count));
  w.put(static_cast<std::uint32_t>(info.stride()));
  w.put_span(std::span<const double>(take.times_s));
  w.put_span(std::span<const float>(take.values));
  auto file =
      impl_->write_data_file("subjects/" + std::to_string(info.subject), "take.fbtak", w.bytes);
  if (!file) return file.failure();
  return impl_->insert_with_files(
      {*file},
      "INSERT INTO takes(subject_id, session_id, fps, shape_names_json, "
      "frame_count, file_id, time_source) VALUES(?,?,?,?,?,?,'file')",
      [&](sql::Statement& stmt, const std::vector<std::int64_t>& ids) {
        stmt.bind_all(info.subject, info.session, info.fps, names_to_json(info.shape_names),
                      info.frame_count, ids[0]);
      });
}

namespace {

// The takes' columns; a reader of a v2 store (not migrated: readers never migrate) derives
// time_source and the shape names the way the v3 migration does.
std::string take_columns(int schema_version) {
  if (schema_version >= 3)
    return "SELECT id, subject_id, session_id, fps, shape_names_json, frame_count, created_at, "
           "file_id, time_source FROM takes ";
  const std::string host = kHostTimestampColumn;
  return "SELECT id, subject_id, session_id, fps, CASE WHEN " + host +
         " THEN json_remove(shape_names_json, '$[#-1]') ELSE shape_names_json END, frame_count, "
         "created_at, file_id, CASE WHEN " +
         host + " THEN 'last_column' ELSE 'frame_rate' END FROM takes ";
}

TakeInfo take_from_row(sql::Statement& stmt) {
  TakeInfo t;
  t.id = stmt.int64(0);
  t.subject = stmt.int64(1);
  t.session = stmt.optional_int64(2);
  t.fps = stmt.real(3);
  t.shape_names = names_from_json(stmt.text(4));
  t.frame_count = stmt.int32(5);
  t.created_at = stmt.text(6);
  return t;
}

}  // namespace

Result<std::vector<TakeInfo>> SessionStore::takes(SubjectId subject) const {
  return impl_->rows<TakeInfo>(
      take_columns(impl_->schema_version) + "WHERE subject_id=? ORDER BY id", subject,
      take_from_row);
}

Result<TakeData> SessionStore::read_take(TakeId id) const {
  auto stmt = sql::prepare(impl_->db.get(), take_columns(impl_->schema_version) + "WHERE id=?");
  if (!stmt) return stmt.failure();
  stmt->bind(1, id);
  auto row = stmt->step();
  if (!row) return row.failure();
  if (!*row) return fail("there is no take " + std::to_string(id) + " in this store");
  TakeData take;
  take.info = take_from_row(*stmt);
  const std::int64_t file_id = stmt->int64(7);
  const std::string time_source = stmt->text(8);
  auto bytes = impl_->load_file(file_id);
  if (!bytes) return bytes.failure();
  if (!decode_take(*bytes, time_source, take))
    return fail("the file of take " + std::to_string(id) +
                " is malformed (its size or layout does not match the database): restore it "
                "from a backup");
  return take;
}

}  // namespace fb
