#include "storage/session_store.hpp"

#include <nlohmann/json.hpp>

#include "storage/frame_record.hpp"
#include "storage/session_store_impl.hpp"

namespace fb {

namespace store_detail {

std::string landmarks_to_json(const std::vector<Landmark>& points) {
  nlohmann::json j = nlohmann::json::array();
  for (const auto& p : points) {
    if (p.has_3d) {
      j.push_back({p.u, p.v, p.x, p.y, p.z});
    } else {
      j.push_back({p.u, p.v});
    }
  }
  return j.dump();
}

Result<std::vector<Landmark>> landmarks_from_json(const std::string& text) {
  auto j = nlohmann::json::parse(text, nullptr, false);
  if (j.is_discarded() || !j.is_array()) return fail("stored landmarks are not a JSON array");
  std::vector<Landmark> out;
  for (const auto& e : j) {
    if (!e.is_array() || (e.size() != 2 && e.size() != 5)) return fail("bad stored landmark");
    Landmark p;
    p.u = e[0].get<float>();
    p.v = e[1].get<float>();
    if (e.size() == 5) {
      p.has_3d = true;
      p.x = e[2].get<float>();
      p.y = e[3].get<float>();
      p.z = e[4].get<float>();
    }
    out.push_back(p);
  }
  return out;
}

std::string scores_to_json(const std::map<std::string, double>& scores) {
  nlohmann::json j = nlohmann::json::object();
  for (const auto& [k, v] : scores) j[k] = v;
  return j.dump();
}

std::map<std::string, double> scores_from_json(const std::string& text) {
  std::map<std::string, double> out;
  auto j = nlohmann::json::parse(text, nullptr, false);
  if (j.is_object()) {
    for (auto it = j.begin(); it != j.end(); ++it) {
      if (it.value().is_number()) out[it.key()] = it.value().get<double>();
    }
  }
  return out;
}

std::string names_to_json(const std::vector<std::string>& names) {
  return nlohmann::json(names).dump();
}

std::vector<std::string> names_from_json(const std::string& text) {
  auto j = nlohmann::json::parse(text, nullptr, false);
  std::vector<std::string> out;
  if (j.is_array()) {
    for (const auto& e : j) {
      if (e.is_string()) out.push_back(e.get<std::string>());
    }
  }
  return out;
}

std::string detail_captures_to_json(const std::vector<RigDetailCapture>& captures) {
  nlohmann::json j = nlohmann::json::array();
  for (const auto& c : captures)
    j.push_back({{"capture", c.capture_index}, {"expression", c.expression}});
  return j.dump();
}

std::vector<RigDetailCapture> detail_captures_from_json(const std::string& text) {
  auto j = nlohmann::json::parse(text, nullptr, false);
  std::vector<RigDetailCapture> out;
  if (!j.is_array()) return out;
  for (const auto& e : j)
    if (e.is_object() && e.value("capture", nlohmann::json()).is_number_integer() &&
        e.value("expression", nlohmann::json()).is_string())
      out.push_back({e["capture"].get<int>(), e["expression"].get<std::string>()});
  return out;
}

CaptureState capture_state_from(const std::string& s) {
  if (s == "capturing") return CaptureState::kCapturing;
  if (s == "rejected") return CaptureState::kRejected;
  if (s == "done") return CaptureState::kDone;
  return CaptureState::kPending;
}

MeshRole mesh_role_from(const std::string& s) {
  if (s == "neutral") return MeshRole::kNeutral;
  if (s == "scan") return MeshRole::kScan;
  return MeshRole::kFitted;
}

std::string sqlite_header_problem(const fs::path& db_path) {
  std::ifstream in(db_path, std::ios::binary);
  if (!in) return "cannot be read (check its permissions)";
  char header[16] = {};
  in.read(header, sizeof header);
  if (in.gcount() == 0) return {};  // empty file: SQLite treats it as a new database
  if (in.gcount() < 16 || std::memcmp(header, "SQLite format 3", 16) != 0) {
    return "is not an SQLite database (garbage or a different file)";
  }
  return {};
}

}  // namespace store_detail

const char* to_string(CaptureState state) {
  switch (state) {
    case CaptureState::kPending:
      return "pending";
    case CaptureState::kCapturing:
      return "capturing";
    case CaptureState::kRejected:
      return "rejected";
    case CaptureState::kDone:
      return "done";
  }
  return "pending";
}

const char* to_string(MeshRole role) {
  switch (role) {
    case MeshRole::kFitted:
      return "fitted";
    case MeshRole::kNeutral:
      return "neutral";
    case MeshRole::kScan:
      return "scan";
  }
  return "fitted";
}

SessionStore::SessionStore(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
SessionStore::SessionStore(SessionStore&&) noexcept = default;
SessionStore& SessionStore::operator=(SessionStore&&) noexcept = default;
SessionStore::~SessionStore() = default;

Result<SessionStore> SessionStore::open(const fs::path& root, const StoreOptions& options) {
  auto impl = std::make_unique<Impl>();
  impl->root = root;
  impl->options = options;
  std::error_code ec;
  if (!fs::is_directory(root, ec)) {
    if (options.read_only || !options.create) {
      return fail("no session store at " + root.string() +
                  " (the folder does not exist): check the path");
    }
    fs::create_directories(root, ec);
    if (ec) {
      return fail("cannot create the session store folder " + root.string() + ": " + ec.message());
    }
  }
  if (!options.read_only) {
    if (auto r = impl->take_writer_lock(); !r) return r.failure();
  }
  if (auto r = impl->open_database(); !r) return r.failure();
  if (!options.read_only) {
    for (const char* top : {"sessions", "subjects", "models"}) {
      fs::create_directories(root / top, ec);
      if (ec) return fail("cannot create " + (root / top).string() + ": " + ec.message());
    }
    if (auto r = impl->clean_orphans(); !r) return r.failure();
  }
  return SessionStore(std::move(impl));
}

const fs::path& SessionStore::root() const {
  return impl_->root;
}
int SessionStore::schema_version() const {
  return impl_->schema_version;
}
bool SessionStore::read_only() const {
  return impl_->options.read_only;
}
int SessionStore::orphans_removed() const {
  return impl_->orphans_removed;
}

// --- subjects and sessions

Result<SubjectId> SessionStore::add_subject(const std::string& name) {
  if (auto r = impl_->require_writer(); !r) return r.failure();
  sqlite3* db = impl_->db.get();
  auto tx = sql::Transaction::begin(db);
  if (!tx) return tx.failure();
  auto stmt = sql::prepare(db, "INSERT INTO subjects(name) VALUES(?)");
  if (!stmt) return stmt.failure();
  stmt->bind(1, name);
  if (auto r = stmt->run(); !r) return r.failure();
  const SubjectId id = sqlite3_last_insert_rowid(db);
  std::error_code ec;
  const fs::path folder = impl_->root / "subjects" / std::to_string(id);
  fs::create_directories(folder, ec);
  if (ec) return fail("cannot create " + folder.string() + ": " + ec.message());
  if (auto r = fsync_directory(folder.parent_path()); !r) return r.failure();
  if (auto r = tx->commit(); !r) return r.failure();
  return id;
}

Result<std::vector<SubjectInfo>> SessionStore::subjects() const {
  return impl_->rows<SubjectInfo>("SELECT id, name, created_at FROM subjects ORDER BY id",
                                  std::nullopt, [](sql::Statement& stmt) {
                                    return SubjectInfo{stmt.int64(0), stmt.text(1), stmt.text(2)};
                                  });
}

Result<SubjectInfo> SessionStore::subject(SubjectId id) const {
  auto all = subjects();
  if (!all) return all.failure();
  for (auto& s : *all) {
    if (s.id == id) return s;
  }
  return fail("there is no subject " + std::to_string(id) + " in this store");
}

Result<SessionId> SessionStore::create_session(SubjectId subject,
                                               const std::vector<std::string>& guide) {
  if (auto r = impl_->require_writer(); !r) return r.failure();
  if (guide.empty()) return fail("a session needs at least one guide expression");
  sqlite3* db = impl_->db.get();
  if (auto r = impl_->ensure_subject(subject); !r) return r.failure();
  auto tx = sql::Transaction::begin(db);
  if (!tx) return tx.failure();
  auto stmt = sql::prepare(db, "INSERT INTO sessions(subject_id, folder) VALUES(?, '')");
  if (!stmt) return stmt.failure();
  stmt->bind(1, subject);
  if (auto r = stmt->run(); !r) return r.failure();
  const SessionId id = sqlite3_last_insert_rowid(db);
  auto recorded = impl_->record_session_folder(id);
  if (!recorded) return recorded.failure();
  const std::string folder = *recorded;
  auto insert = sql::prepare(db, "INSERT INTO captures(session_id, idx, expression) VALUES(?,?,?)");
  if (!insert) return insert.failure();
  for (std::size_t i = 0; i < guide.size(); ++i) {
    insert->reset();
    insert->bind_all(id, static_cast<std::int64_t>(i), guide[i]);
    if (auto r = insert->run(); !r) return r.failure();
  }
  // The folder exists before the row commits; a crash in between leaves an empty folder that a
  // later session with the same id simply reuses.
  std::error_code ec;
  fs::create_directories(impl_->root / folder, ec);
  if (ec) return fail("cannot create " + (impl_->root / folder).string() + ": " + ec.message());
  if (auto r = fsync_directory(impl_->root / "sessions"); !r) return r.failure();
  if (auto r = tx->commit(); !r) return r.failure();
  return id;
}

Result<SessionInfo> SessionStore::session(SessionId id) const {
  auto all = sessions();
  if (!all) return all.failure();
  for (auto& s : *all) {
    if (s.id == id) return s;
  }
  return fail("there is no session " + std::to_string(id) + " in this store");
}

Result<std::vector<SessionInfo>> SessionStore::sessions() const {
  const std::string query =
      "SELECT s.id, s.subject_id, s.created_at, s.state, s.folder, "
      "(SELECT count(*) FROM captures c WHERE c.session_id=s.id), "
      "(SELECT count(*) FROM captures c WHERE c.session_id=s.id AND c.state='done'), " +
      std::string(impl_->schema_version >= 4 ? "s.calibration_json" : "NULL") +
      (impl_->schema_version >= 5 ? ", s.origin_booth, s.origin_id" : ", NULL, NULL") +
      " FROM sessions s ORDER BY s.id";
  return impl_->rows<SessionInfo>(query, std::nullopt, [&](sql::Statement& stmt) {
    SessionInfo s;
    s.id = stmt.int64(0);
    s.subject = stmt.int64(1);
    s.created_at = stmt.text(2);
    s.complete = stmt.text(3) == "complete";
    s.folder = impl_->root / stmt.text(4);
    s.capture_count = stmt.int32(5);
    s.done_count = stmt.int32(6);
    s.calibration_json = stmt.text(7);
    s.origin_booth = stmt.text(8);
    s.origin_session = stmt.int64(9);
    return s;
  });
}

Result<void> SessionStore::set_session_calibration(SessionId session,
                                                   const std::string& device_json) {
  if (auto r = impl_->require_writer(); !r) return r.failure();
  if (auto folder = impl_->session_folder(session); !folder) return folder.failure();
  auto stmt = sql::prepare(impl_->db.get(), "UPDATE sessions SET calibration_json=? WHERE id=?");
  if (!stmt) return stmt.failure();
  stmt->bind_all(device_json, session);
  return stmt->run();
}

// --- captures

Result<std::vector<CaptureInfo>> SessionStore::captures(SessionId session) const {
  if (auto folder = impl_->session_folder(session); !folder) return folder.failure();
  return impl_->query_captures("WHERE session_id=?1 ORDER BY idx", session);
}

Result<CaptureInfo> SessionStore::capture(SessionId session, int index) const {
  return impl_->one_capture(session, index);
}

Result<std::optional<CaptureInfo>> SessionStore::next_capture(SessionId session) const {
  if (auto folder = impl_->session_folder(session); !folder) return folder.failure();
  auto list =
      impl_->query_captures("WHERE session_id=?1 AND state<>'done' ORDER BY idx LIMIT 1", session);
  if (!list) return list.failure();
  if (list->empty()) return std::optional<CaptureInfo>();
  return std::optional<CaptureInfo>(list->front());
}

Result<void> SessionStore::begin_capture(SessionId session, int index) {
  if (auto r = impl_->require_writer(); !r) return r;
  auto c = impl_->one_capture(session, index);
  if (!c) return c.failure();
  if (c->state == CaptureState::kDone) {
    return fail("capture " + std::to_string(index) + " (" + c->expression + ") of session " +
                std::to_string(session) + " is already done");
  }
  auto stmt = sql::prepare(impl_->db.get(),
                           "UPDATE captures SET state='capturing', attempts=attempts+1 WHERE id=?");
  if (!stmt) return stmt.failure();
  stmt->bind(1, c->id);
  return stmt->run();
}

Result<void> SessionStore::reject_capture(SessionId session, int index,
                                          const std::map<std::string, double>& qa_scores) {
  if (auto r = impl_->require_writer(); !r) return r;
  auto c = impl_->one_capture(session, index);
  if (!c) return c.failure();
  if (c->state == CaptureState::kDone) {
    return fail("capture " + std::to_string(index) + " is already done; it cannot be rejected");
  }
  auto stmt =
      sql::prepare(impl_->db.get(), "UPDATE captures SET state='rejected', qa_json=? WHERE id=?");
  if (!stmt) return stmt.failure();
  stmt->bind_all(scores_to_json(qa_scores), c->id);
  return stmt->run();
}

namespace store_detail {

Result<FrameSequence> write_frame_sequence(const SessionStore::Impl& impl,
                                           const std::string& folder, const std::string& stem,
                                           const CaptureInput& input, std::size_t frame_count) {
  const bool from_source = input.frames.empty();
  FrameSequence out;
  const std::string rel = folder + "/" + stem + "-frames-" + random_token(8) + ".fbseq";
  auto file = DurableFile::create(impl.root / rel, impl.file_hooks());
  if (!file) return impl.folder_missing_or(folder, file.error());
  ByteWriter header;
  header.put_magic(kSeqMagic);
  header.put(static_cast<std::uint32_t>(frame_count));
  header.put(std::uint32_t{0});
  if (auto r = file->append(header.bytes); !r) return r.failure();
  RgbdFrame scratch;
  for (std::size_t i = 0; i < frame_count; ++i) {
    if (from_source) {
      if (auto r = input.read_frame(i, scratch); !r) return r.failure();
    }
    const RgbdFrame& f = from_source ? scratch : input.frames[i];
    out.offsets.push_back(file->size());
    out.headers.push_back(frame_record::header_of(f, /*with_raw_disparity=*/true));
    auto sink = [&](const void* data, std::size_t size) { return file->append(data, size); };
    if (auto r = frame_record::write(f, /*with_raw_disparity=*/true, sink); !r) return r.failure();
  }
  if (auto r = file->commit(); !r) return r.failure();
  out.file = {rel, file->size(), file->sha256()};
  return out;
}

}  // namespace store_detail

Result<void> SessionStore::commit_capture(SessionId session, int index, const CaptureInput& input) {
  if (auto r = impl_->require_writer(); !r) return r;
  auto c = impl_->one_capture(session, index);
  if (!c) return c.failure();
  if (c->state == CaptureState::kDone) {
    return fail("capture " + std::to_string(index) + " (" + c->expression + ") of session " +
                std::to_string(session) + " is already done; nothing was changed");
  }
  const bool from_source = input.frames.empty();
  const std::size_t frame_count = from_source ? input.frame_count : input.frames.size();
  if (frame_count == 0 || (from_source && !input.read_frame))
    return fail("a capture needs at least one frame");
  auto folder = impl_->session_folder(session);
  if (!folder) return folder.failure();
  const std::string stem = "c" + std::to_string(index) + "-a" + std::to_string(c->attempts);

  // 1. The frame sequence.
  auto sequence = write_frame_sequence(*impl_, *folder, stem, input, frame_count);
  if (!sequence) return sequence.failure();
  std::vector<Impl::StoredFile> written = {sequence->file};
  const std::vector<std::uint64_t>& offsets = sequence->offsets;
  const std::vector<frame_record::Header>& headers = sequence->headers;
  // 2. The fused depth map.
  if (!input.fused_depth.empty()) {
    ByteWriter w;
    w.put_magic(kDepthMagic);
    w.put(static_cast<std::int32_t>(input.fused_depth.width));
    w.put(static_cast<std::int32_t>(input.fused_depth.height));
    w.put_span(std::span<const std::uint16_t>(input.fused_depth.pixels));
    auto f = impl_->write_data_file(*folder, stem + "-fused.fbdep", w.bytes);
    if (!f) {
      impl_->discard(written);
      return f.failure();
    }
    written.push_back(*f);
  }

  // 3. One transaction makes the capture visible, durably (synchronous=FULL for this commit:
  // a finished capture must survive a power cut, not only a process crash).
  sqlite3* db = impl_->db.get();
  auto commit = [&]() -> Result<void> {
    if (auto r = sql::exec(db, "PRAGMA synchronous=FULL"); !r) return r;
    auto tx = sql::Transaction::begin(db);
    if (!tx) return tx.failure();
    std::vector<std::int64_t> ids;
    for (const auto& f : written) {
      auto id = impl_->insert_file_row(f);
      if (!id) return id.failure();
      ids.push_back(*id);
    }
    auto frame =
        sql::prepare(db,
                     "INSERT INTO frames(capture_id, seq, depth_host_time_s, color_host_time_s, "
                     "depth_device_ts, color_device_ts, file_id, offset) VALUES(?,?,?,?,?,?,?,?)");
    if (!frame) return frame.failure();
    for (std::size_t i = 0; i < frame_count; ++i) {
      const frame_record::Header& h = headers[i];
      frame->reset();
      frame->bind_all(c->id, static_cast<std::int64_t>(i), h.depth_host_time_s, h.color_host_time_s,
                      static_cast<std::int64_t>(h.depth_device_timestamp),
                      static_cast<std::int64_t>(h.color_device_timestamp), ids[0],
                      static_cast<std::int64_t>(offsets[i]));
      if (auto r = frame->run(); !r) return r;
    }
    if (!input.landmarks.empty()) {
      auto lm = sql::prepare(db,
                             "INSERT OR REPLACE INTO landmarks(capture_id, source, points_json) "
                             "VALUES(?, 'automatic', ?)");
      if (!lm) return lm.failure();
      lm->bind_all(c->id, landmarks_to_json(input.landmarks));
      if (auto r = lm->run(); !r) return r;
    }
    auto update = sql::prepare(db, std::string("UPDATE captures SET state='done', qa_json=?, "
                                               "frame_count=?, frames_file_id=?, "
                                               "fused_file_id=?, completed_at=") +
                                       kNow + " WHERE id=?");
    if (!update) return update.failure();
    update->bind_all(scores_to_json(input.qa_scores), static_cast<std::int64_t>(frame_count),
                     ids[0], ids.size() > 1 ? std::optional<std::int64_t>(ids[1]) : std::nullopt,
                     c->id);
    if (auto r = update->run(); !r) return r;
    auto complete = sql::prepare(db,
                                 "UPDATE sessions SET state='complete' WHERE id=?1 AND NOT EXISTS "
                                 "(SELECT 1 FROM captures WHERE session_id=?1 AND state<>'done')");
    if (!complete) return complete.failure();
    complete->bind(1, session);
    if (auto r = complete->run(); !r) return r;
    impl_->phase(StorePhase::kCommitting);
    return tx->commit();
  };
  auto committed = commit();
  (void)sql::exec(db, "PRAGMA synchronous=NORMAL");
  impl_->phase(StorePhase::kIdle);
  if (!committed) {
    impl_->discard(written);
    return fail("capture " + std::to_string(index) +
                " was not stored: " + committed.error().message);
  }
  return success();
}

Result<CaptureData> SessionStore::read_capture(SessionId session, int index,
                                               const CaptureReadOptions& options) const {
  auto c = impl_->one_capture(session, index);
  if (!c) return c.failure();
  if (c->state != CaptureState::kDone) {
    return fail("capture " + std::to_string(index) + " (" + c->expression + ") of session " +
                std::to_string(session) + " is " + to_string(c->state) + ", not done");
  }
  auto ids = sql::prepare(impl_->db.get(),
                          "SELECT frames_file_id, fused_file_id FROM captures WHERE id=?");
  if (!ids) return ids.failure();
  ids->bind(1, c->id);
  if (auto row = ids->step(); !row || !*row) return fail("capture row vanished while reading");
  const auto frames_file = ids->int64(0);
  const auto fused_file = ids->optional_int64(1);

  CaptureData out;
  out.info = *c;
  auto file = impl_->data_file(frames_file);
  if (!file) return file.failure();
  VerifiedReader in(file->path);
  if (!in.is_open()) return fail("cannot open " + file->path.string());
  const std::string bad = "the frame file of capture " + std::to_string(index) + " is malformed";
  // On a short or inconsistent file the checksum decides whether it is damaged (changed after
  // the commit) or malformed (written wrong).
  auto decoded =
      decode_frame_sequence(in, file->bytes, c->frame_count, options.max_frames, out.frames, bad);
  if (!in.matches(file->bytes, file->sha256)) return fail(Impl::damaged(*file));
  if (!decoded) return decoded.failure();
  if (fused_file) {
    auto fused = impl_->load_file(*fused_file);
    if (!fused) return fused.failure();
    if (!decode_fused_depth(*fused, out.fused_depth)) {
      return fail("the fused depth file of capture " + std::to_string(index) + " is malformed");
    }
  }
  auto lm = sql::prepare(impl_->db.get(),
                         "SELECT source, points_json FROM landmarks WHERE capture_id=? "
                         "ORDER BY source='operator' DESC LIMIT 1");
  if (!lm) return lm.failure();
  lm->bind(1, c->id);
  auto row = lm->step();
  if (!row) return row.failure();
  if (*row) {
    out.landmark_source =
        lm->text(0) == "operator" ? LandmarkSource::kOperator : LandmarkSource::kAutomatic;
    auto points = landmarks_from_json(lm->text(1));
    if (!points) return points.failure();
    out.landmarks = std::move(*points);
  }
  return out;
}

Result<void> SessionStore::set_operator_landmarks(SessionId session, int index,
                                                  const std::vector<Landmark>& landmarks) {
  if (auto r = impl_->require_writer(); !r) return r;
  auto c = impl_->one_capture(session, index);
  if (!c) return c.failure();
  if (c->state != CaptureState::kDone) {
    return fail("capture " + std::to_string(index) +
                " is not done yet; landmarks can be "
                "corrected once it is stored");
  }
  auto stmt = sql::prepare(impl_->db.get(),
                           std::string("INSERT INTO landmarks(capture_id, source, points_json) "
                                       "VALUES(?, 'operator', ?) ON CONFLICT(capture_id, source) "
                                       "DO UPDATE SET points_json=excluded.points_json, "
                                       "created_at=") +
                               kNow);
  if (!stmt) return stmt.failure();
  stmt->bind_all(c->id, landmarks_to_json(landmarks));
  return stmt->run();
}

// --- meshes, rigs, models, takes

Result<VerifyReport> SessionStore::verify() const {
  VerifyReport report;
  auto check = sql::query_text(impl_->db.get(), "PRAGMA integrity_check");
  if (!check) return check.failure();
  report.integrity = *check;
  auto fk = sql::prepare(impl_->db.get(), "PRAGMA foreign_key_check");
  if (!fk) return fk.failure();
  if (auto row = fk->step(); !row) {
    return row.failure();
  } else if (*row) {
    report.problems.push_back("foreign key violation in table " + fk->text(0));
  }
  auto stmt = sql::prepare(impl_->db.get(), "SELECT relpath, bytes, sha256 FROM files ORDER BY id");
  if (!stmt) return stmt.failure();
  for (;;) {
    auto row = stmt->step();
    if (!row) return row.failure();
    if (!*row) break;
    ++report.files_checked;
    const fs::path path = impl_->root / stmt->text(0);
    std::error_code ec;
    const auto size = fs::file_size(path, ec);
    if (ec) {
      report.problems.push_back(path.string() + ": missing");
      continue;
    }
    if (size != static_cast<std::uintmax_t>(stmt->int64(1))) {
      report.problems.push_back(path.string() + ": size differs");
      continue;
    }
    auto sha = sha256_file(path);
    if (!sha || *sha != stmt->text(2))
      report.problems.push_back(path.string() + ": SHA-256 differs");
  }
  return report;
}

}  // namespace fb
