// Internal to storage/ (not part of the API): the session store's Impl and what its source files
// share. session_store.cpp: open, subjects, sessions, captures, verify; session_store_schema.cpp:
// the migrations; session_store_products.cpp: meshes, rigs, models, takes.
#pragma once

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <system_error>
#include <vector>

#include "storage/data_codec.hpp"
#include "storage/durable_file.hpp"
#include "storage/frame_record.hpp"
#include "storage/session_store.hpp"
#include "storage/sha256.hpp"
#include "storage/sqlite_util.hpp"

namespace fb {

static_assert(std::endian::native == std::endian::little,
              "data files are written little-endian by memcpy; add byte swapping for big-endian");

namespace store_detail {

namespace fs = std::filesystem;

inline constexpr std::int64_t kApplicationId = 0x46427468;  // "FBth", PRAGMA application_id
inline constexpr const char* kLockFileName = ".writer.lock";
inline constexpr const char* kNow = "strftime('%Y-%m-%dT%H:%M:%fZ','now')";

// A take from before v3 whose last "shape" is the host's timestamp column (the v3 migration and
// readers of v2 stores apply the same test).
inline constexpr const char* kHostTimestampColumn =
    "json_valid(shape_names_json) AND json_type(shape_names_json) = 'array' AND "
    "json_extract(shape_names_json, '$[#-1]') = 'timestamp_s'";

// Readers open stores of this schema or newer: v3 only added a column readers can do without.
inline constexpr int kOldestReadableSchema = 2;

// Each migration moves the schema from version (index) to version (index + 1)
// (session_store_schema.cpp).
const std::vector<std::string>& migrations();

// Reads a data file front to back in one pass, hashing everything it reads, so that a caller
// can decode part of a large file into place and still check the whole file's SHA-256.
class VerifiedReader {
 public:
  explicit VerifiedReader(const fs::path& path) : in_(path, std::ios::binary) {}
  bool is_open() const { return in_.is_open(); }
  bool read(void* out, std::size_t n) {
    if (n == 0) return true;
    in_.read(static_cast<char*>(out), static_cast<std::streamsize>(n));
    const auto got = static_cast<std::size_t>(in_.gcount());
    sha_.update(out, got);
    position_ += got;
    return got == n;
  }
  bool skip(std::size_t n) {
    char buffer[64 * 1024];
    while (n > 0) {
      const std::size_t step = std::min(n, sizeof buffer);
      if (!read(buffer, step)) return false;
      n -= step;
    }
    return true;
  }
  std::uint64_t position() const { return position_; }
  // Reads what is left; true when the file had exactly `bytes` bytes with digest `sha256`.
  bool matches(std::uint64_t bytes, const std::string& sha256) {
    char buffer[64 * 1024];
    while (read(buffer, sizeof buffer)) {
    }
    return position_ == bytes && sha_.hex_digest() == sha256;
  }

 private:
  std::ifstream in_;
  Sha256 sha_;
  std::uint64_t position_ = 0;
};

// Row and file helpers (session_store.cpp).
std::string landmarks_to_json(const std::vector<Landmark>& points);
Result<std::vector<Landmark>> landmarks_from_json(const std::string& text);
std::string scores_to_json(const std::map<std::string, double>& scores);
std::map<std::string, double> scores_from_json(const std::string& text);
std::string names_to_json(const std::vector<std::string>& names);
std::vector<std::string> names_from_json(const std::string& text);
std::string detail_captures_to_json(const std::vector<RigDetailCapture>& captures);
std::vector<RigDetailCapture> detail_captures_from_json(const std::string& text);
CaptureState capture_state_from(const std::string& s);
MeshRole mesh_role_from(const std::string& s);
// Why a file is not an SQLite database (empty when it is one or is empty).
std::string sqlite_header_problem(const fs::path& db_path);

}  // namespace store_detail

// Only the store's own source files include this header.
using namespace store_detail;

struct SessionStore::Impl {
  fs::path root;
  StoreOptions options;
  sql::Connection db;
  UniqueFd lock;  // flock'ed by the writer for its lifetime
  int schema_version = 0;
  int orphans_removed = 0;

  struct StoredFile {
    std::string relpath;
    std::uint64_t bytes = 0;
    std::string sha256;
  };

  void phase(StorePhase p) const {
    if (options.on_phase) options.on_phase(p);
  }

  DurableFileHooks file_hooks() const {
    DurableFileHooks hooks;
    hooks.inject_write_error = options.inject_write_error;
    if (options.on_phase) {
      hooks.on_step = [this](int step) {
        phase(step == 1   ? StorePhase::kWritingFile
              : step == 2 ? StorePhase::kSyncingFile
                          : StorePhase::kRenaming);
      };
    }
    return hooks;
  }

  Result<void> require_writer() const {
    if (options.read_only) {
      return fail("this session store was opened read-only; writes go through the one writer");
    }
    return success();
  }

  // Writes a data file under `folder` (relative to root) durably, without a database row yet.
  Result<StoredFile> write_data_file(const std::string& folder, const std::string& stem,
                                     std::span<const std::uint8_t> bytes) const {
    const std::string rel = folder + "/" + stem + "-" + random_token(8);
    auto file = DurableFile::create(root / rel, file_hooks());
    if (!file) return folder_missing_or(folder, file.error());
    if (auto r = file->append(bytes); !r) return r.failure();
    if (auto r = file->commit(); !r) return r.failure();
    return StoredFile{rel, file->size(), file->sha256()};
  }

  Failure folder_missing_or(const std::string& folder, const Error& error) const {
    std::error_code ec;
    if (!fs::is_directory(root / folder, ec)) {
      return fail("the data folder " + (root / folder).string() +
                  " is missing (moved or deleted?): restore it from a backup; the database "
                  "still lists everything stored in it, and nothing was changed");
    }
    return fail(error);
  }

  Result<std::int64_t> insert_file_row(const StoredFile& f) const {
    auto stmt = sql::prepare(db.get(), "INSERT INTO files(relpath, bytes, sha256) VALUES(?,?,?)");
    if (!stmt) return stmt.failure();
    stmt->bind_all(f.relpath, static_cast<std::int64_t>(f.bytes), f.sha256);
    if (auto r = stmt->run(); !r) return r.failure();
    return sqlite3_last_insert_rowid(db.get());
  }

  // A new session's folder, sessions/<id> under the root, recorded in its row.
  Result<std::string> record_session_folder(std::int64_t session) const {
    const std::string folder = "sessions/" + std::to_string(session);
    auto update = sql::prepare(db.get(), "UPDATE sessions SET folder=? WHERE id=?");
    if (!update) return update.failure();
    update->bind_all(folder, session);
    if (auto r = update->run(); !r) return r.failure();
    return folder;
  }

  // Best effort: removes data files whose commit failed (the orphan cleanup would get them
  // at the next open anyway).
  void discard(const std::vector<StoredFile>& files) const {
    for (const auto& f : files) {
      std::error_code ec;
      fs::remove(root / f.relpath, ec);
    }
  }

  // One row over data files already written durably, in one transaction: the files' rows, then
  // `insert_sql` bound by `bind(statement, the files' row ids)`; returns its row id. When anything
  // fails the files are removed again, so a failed add leaves nothing behind.
  template <class Bind>
  Result<std::int64_t> insert_with_files(const std::vector<StoredFile>& files,
                                         std::string_view insert_sql, Bind bind) const {
    auto insert = [&]() -> Result<std::int64_t> {
      auto tx = sql::Transaction::begin(db.get());
      if (!tx) return tx.failure();
      std::vector<std::int64_t> file_ids;
      for (const auto& f : files) {
        auto id = insert_file_row(f);
        if (!id) return id.failure();
        file_ids.push_back(*id);
      }
      auto stmt = sql::prepare(db.get(), insert_sql);
      if (!stmt) return stmt.failure();
      bind(*stmt, file_ids);
      if (auto r = stmt->run(); !r) return r.failure();
      const std::int64_t row = sqlite3_last_insert_rowid(db.get());
      if (auto r = tx->commit(); !r) return r.failure();
      return row;
    };
    auto row = insert();
    if (!row) discard(files);
    return row;
  }

  // Every row `query` selects, each made into a T by `read(statement)`; `key`, when given, is
  // bound to the query's one parameter.
  template <class T, class Read>
  Result<std::vector<T>> rows(std::string_view query, std::optional<std::int64_t> key,
                              Read read) const {
    std::vector<T> out;
    auto stmt = sql::prepare(db.get(), query);
    if (!stmt) return stmt.failure();
    if (key) stmt->bind(1, *key);
    for (;;) {
      auto row = stmt->step();
      if (!row) return row.failure();
      if (!*row) break;
      out.push_back(read(*stmt));
    }
    return out;
  }

  struct DataFile {
    fs::path path;
    std::uint64_t bytes = 0;
    std::string sha256;
  };
  // Where a committed data file is, with the size and SHA-256 committed for it; a missing file
  // or folder is an error that says what to restore.
  Result<DataFile> data_file(std::int64_t file_id) const {
    auto stmt = sql::prepare(db.get(), "SELECT relpath, bytes, sha256 FROM files WHERE id=?");
    if (!stmt) return stmt.failure();
    stmt->bind(1, file_id);
    auto row = stmt->step();
    if (!row) return row.failure();
    if (!*row) return fail("data file #" + std::to_string(file_id) + " is not in the database");
    const std::string rel = stmt->text(0);
    DataFile f{root / rel, static_cast<std::uint64_t>(stmt->int64(1)), stmt->text(2)};
    std::error_code ec;
    if (!fs::exists(f.path, ec)) {
      const fs::path folder = f.path.parent_path();
      if (!fs::is_directory(folder, ec)) {
        return fail("the data folder " + folder.string() +
                    " is missing (moved or deleted?): restore it from a backup to read " + rel +
                    "; the database entries are kept");
      }
      return fail("data file " + f.path.string() +
                  " is missing: restore it from a backup (the database entry is kept)");
    }
    return f;
  }
  static Error damaged(const DataFile& f) {
    return Error{"data file " + f.path.string() + " is damaged (size or SHA-256 differs from " +
                 "what was committed): restore it from a backup"};
  }

  // Reads a committed data file and checks its size and SHA-256 against the database.
  // `verify`: the SHA-256 as well as the size (a caller re-reading a file it has verified in
  // this run may skip the hash).
  Result<std::vector<std::uint8_t>> load_file(std::int64_t file_id, bool verify = true) const {
    auto f = data_file(file_id);
    if (!f) return f.failure();
    auto data = read_file_bytes(f->path);
    if (!data) return data.failure();
    if (data->size() != f->bytes || (verify && sha256_hex(*data) != f->sha256))
      return fail(damaged(*f));
    return data;
  }

  Result<std::string> session_folder(SessionId session) const {
    auto stmt = sql::prepare(db.get(), "SELECT folder FROM sessions WHERE id=?");
    if (!stmt) return stmt.failure();
    stmt->bind(1, session);
    auto row = stmt->step();
    if (!row) return row.failure();
    if (!*row) return fail("there is no session " + std::to_string(session) + " in this store");
    return stmt->text(0);
  }

  Result<void> ensure_subject(SubjectId subject) const {
    auto n = sql::query_int(db.get(),
                            "SELECT count(*) FROM subjects WHERE id=" + std::to_string(subject));
    if (!n) return n.failure();
    if (*n == 0) return fail("there is no subject " + std::to_string(subject) + " in this store");
    return success();
  }

  Result<void> migrate() {
    const auto& list = migrations();
    const int target = options.migrate_to > 0
                           ? std::min<int>(options.migrate_to, static_cast<int>(list.size()))
                           : static_cast<int>(list.size());
    while (schema_version < target) {
      auto tx = sql::Transaction::begin(db.get());
      if (!tx) return tx.failure();
      if (auto r = sql::exec(db.get(), list[static_cast<std::size_t>(schema_version)]); !r) {
        return fail("migrating the store to schema v" + std::to_string(schema_version + 1) +
                    " failed: " + r.error().message);
      }
      const int next = schema_version + 1;
      if (auto r = sql::exec(db.get(), "PRAGMA user_version=" + std::to_string(next)); !r) {
        return r.failure();
      }
      if (auto r = sql::exec(db.get(), "PRAGMA application_id=" + std::to_string(kApplicationId));
          !r) {
        return r.failure();
      }
      if (auto r = tx->commit(); !r) return r.failure();
      schema_version = next;
    }
    return success();
  }

  // Deletes temporaries and data files no committed row references: what a crash between
  // "file written" and "row committed" leaves behind. Runs under the writer lock, so no file
  // in flight can be mistaken for an orphan.
  Result<void> clean_orphans() {
    std::set<std::string> referenced;
    {
      auto stmt = sql::prepare(db.get(), "SELECT relpath FROM files");
      if (!stmt) return stmt.failure();
      for (;;) {
        auto row = stmt->step();
        if (!row) return row.failure();
        if (!*row) break;
        referenced.insert(stmt->text(0));
      }
    }
    for (const char* top : {"sessions", "subjects", "models"}) {
      std::error_code ec;
      const fs::path dir = root / top;
      if (!fs::is_directory(dir, ec)) continue;
      for (auto it = fs::recursive_directory_iterator(dir, ec);
           !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
        if (!it->is_regular_file(ec)) continue;
        const std::string rel = fs::relative(it->path(), root, ec).generic_string();
        const std::string name = it->path().filename().string();
        if (name.rfind(kDurableTempPrefix, 0) == 0 || referenced.count(rel) == 0) {
          std::error_code rm;
          if (fs::remove(it->path(), rm)) ++orphans_removed;
        }
      }
    }
    return success();
  }

  Result<void> open_database() {
    const fs::path db_path = root / kSessionStoreDatabaseName;
    std::error_code ec;
    const bool exists = fs::exists(db_path, ec);
    if (!exists && (options.read_only || !options.create)) {
      return fail("no session store at " + root.string() + " (" + db_path.filename().string() +
                  " is missing): check the path, or open it as the writer to create it");
    }
    if (exists) {
      if (const std::string problem = sqlite_header_problem(db_path); !problem.empty()) {
        return fail("the session store database " + db_path.string() + " " + problem +
                    ": move it aside and restore it from a backup; facebooth did not modify it");
      }
    }
    sqlite3* raw = nullptr;
    const int flags =
        (options.read_only ? SQLITE_OPEN_READONLY : SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE) |
        SQLITE_OPEN_NOMUTEX;
    const int rc = sqlite3_open_v2(db_path.c_str(), &raw, flags, nullptr);
    db.reset(raw);  // owns the handle even when the open failed
    if (rc != SQLITE_OK) return fail(sql::describe(db.get(), rc, "opening " + db_path.string()));
    sqlite3_busy_timeout(db.get(), 5000);
    sqlite3_extended_result_codes(db.get(), 1);

    // Identify the file before changing anything in it.
    auto version = sql::query_int(db.get(), "PRAGMA user_version");
    if (!version) return fail("cannot read " + db_path.string() + ": " + version.error().message);
    auto app_id = sql::query_int(db.get(), "PRAGMA application_id");
    if (!app_id) return app_id.failure();
    const int latest = static_cast<int>(migrations().size());
    if (*version > latest) {
      return fail("the session store " + db_path.string() + " has schema v" +
                  std::to_string(*version) + ", newer than this facebooth understands (v" +
                  std::to_string(latest) +
                  "): update facebooth to open it; the file was not modified");
    }
    if (*version == 0) {
      auto tables = sql::query_int(db.get(), "SELECT count(*) FROM sqlite_master");
      if (!tables) return tables.failure();
      if (*tables > 0) {
        return fail(db_path.string() +
                    " is an SQLite database but not a facebooth session store: use another "
                    "folder; the file was not modified");
      }
    } else if (*app_id != kApplicationId) {
      return fail(db_path.string() +
                  " is an SQLite database of another application: use another folder; the "
                  "file was not modified");
    }
    auto check = sql::query_text(db.get(), "PRAGMA quick_check");
    if (!check)
      return fail("the session store " + db_path.string() +
                  " is damaged: " + check.error().message);
    if (*check != "ok") {
      return fail("the session store " + db_path.string() + " is damaged (" + *check +
                  "): move it aside and restore it from a backup; facebooth did not modify it");
    }
    schema_version = static_cast<int>(*version);
    if (options.read_only) {
      if (schema_version < kOldestReadableSchema) {
        return fail("the session store " + root.string() + " has schema v" +
                    std::to_string(schema_version) + " (current v" + std::to_string(latest) +
                    "): open it once as the writer to migrate it");
      }
      return sql::exec(db.get(), "PRAGMA query_only=ON");
    }
    // WAL: readers on other connections never block the writer, and a crash never leaves a
    // half-applied transaction. NORMAL is durable enough for bookkeeping; capture commits
    // switch to FULL (see commit_capture).
    auto mode = sql::query_text(db.get(), "PRAGMA journal_mode=WAL");
    if (!mode) return mode.failure();
    if (*mode != "wal") return fail("cannot switch " + db_path.string() + " to WAL mode");
    if (auto r = sql::exec(db.get(), "PRAGMA foreign_keys=ON; PRAGMA synchronous=NORMAL"); !r) {
      return r;
    }
    return migrate();
  }

  Result<void> take_writer_lock() {
    const fs::path path = root / kLockFileName;
    UniqueFd fd(::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644));
    if (!fd.valid()) {
      return fail("cannot create the lock file " + path.string() + ": " + std::strerror(errno) +
                  " (is the store folder writable?)");
    }
    if (::flock(fd.get(), LOCK_EX | LOCK_NB) != 0) {
      return fail("another facebooth process is writing the session store " + root.string() +
                  ": stop it (the daemon?) or open the store read-only");
    }
    lock = std::move(fd);
    return success();
  }

  Result<CaptureInfo> capture_from_row(sql::Statement& s) const {
    CaptureInfo c;
    c.id = s.int64(0);
    c.session = s.int64(1);
    c.index = s.int32(2);
    c.expression = s.text(3);
    c.state = capture_state_from(s.text(4));
    c.attempts = s.int32(5);
    c.qa_scores = scores_from_json(s.text(6));
    c.frame_count = s.int32(7);
    c.completed_at = s.text(8);
    return c;
  }
  static constexpr const char* kCaptureColumns =
      "SELECT id, session_id, idx, expression, state, attempts, qa_json, frame_count, "
      "coalesce(completed_at,''), frames_file_id, fused_file_id FROM captures ";

  Result<std::vector<CaptureInfo>> query_captures(const std::string& where, std::int64_t a,
                                                  std::int64_t b = 0) const {
    auto stmt = sql::prepare(db.get(), std::string(kCaptureColumns) + where);
    if (!stmt) return stmt.failure();
    stmt->bind(1, a);
    if (where.find("?2") != std::string::npos) stmt->bind(2, b);
    std::vector<CaptureInfo> out;
    for (;;) {
      auto row = stmt->step();
      if (!row) return row.failure();
      if (!*row) break;
      auto c = capture_from_row(*stmt);
      if (!c) return c.failure();
      out.push_back(std::move(*c));
    }
    return out;
  }

  Result<CaptureInfo> one_capture(SessionId session, int index) const {
    auto list = query_captures("WHERE session_id=?1 AND idx=?2", session, index);
    if (!list) return list.failure();
    if (list->empty()) {
      auto folder = session_folder(session);
      if (!folder) return folder.failure();
      return fail("session " + std::to_string(session) + " has no capture " +
                  std::to_string(index));
    }
    return list->front();
  }
};

namespace store_detail {

// A capture's .fbseq file, streamed frame by frame (a capture is tens of megabytes), with what
// the frames table needs: each frame's header and byte offset (session_store.cpp; the import
// writes its captures the same way).
struct FrameSequence {
  SessionStore::Impl::StoredFile file;
  std::vector<std::uint64_t> offsets;
  std::vector<frame_record::Header> headers;
};
Result<FrameSequence> write_frame_sequence(const SessionStore::Impl& impl,
                                           const std::string& folder, const std::string& stem,
                                           const CaptureInput& input, std::size_t frame_count);

}  // namespace store_detail

}  // namespace fb
