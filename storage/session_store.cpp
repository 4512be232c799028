#include "storage/session_store.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <system_error>

#include "storage/durable_file.hpp"
#include "storage/frame_record.hpp"
#include "storage/sha256.hpp"
#include "storage/sqlite_util.hpp"

namespace fb {

static_assert(std::endian::native == std::endian::little,
              "data files are written little-endian by memcpy; add byte swapping for big-endian");

namespace fs = std::filesystem;

namespace {

constexpr std::int64_t kApplicationId = 0x46427468;  // "FBth", PRAGMA application_id
constexpr const char* kLockFileName = ".writer.lock";
constexpr const char* kNow = "strftime('%Y-%m-%dT%H:%M:%fZ','now')";

// A take from before v3 whose last "shape" is the host's timestamp column (the v3 migration and
// readers of v2 stores apply the same test).
constexpr const char* kHostTimestampColumn =
    "json_valid(shape_names_json) AND json_type(shape_names_json) = 'array' AND "
    "json_extract(shape_names_json, '$[#-1]') = 'timestamp_s'";

// Readers open stores of this schema or newer: v3 only added a column readers can do without.
constexpr int kOldestReadableSchema = 2;

// Each migration moves the schema from version (index) to version (index + 1). Never edit a
// released migration: add a new one, so every store upgrades along the same path.
const std::vector<std::string>& migrations() {
  static const std::vector<std::string> list = {
      // v1: capture sessions and their products.
      R"sql(
CREATE TABLE files(
  id INTEGER PRIMARY KEY,
  relpath TEXT NOT NULL UNIQUE,        -- relative to the store root
  bytes INTEGER NOT NULL,
  sha256 TEXT NOT NULL,
  created_at TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ','now')));
CREATE TABLE subjects(
  id INTEGER PRIMARY KEY,
  name TEXT NOT NULL,
  created_at TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ','now')));
CREATE TABLE sessions(
  id INTEGER PRIMARY KEY,
  subject_id INTEGER NOT NULL REFERENCES subjects(id),
  state TEXT NOT NULL DEFAULT 'open' CHECK(state IN ('open','complete')),
  folder TEXT NOT NULL,                -- relative to the store root
  created_at TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ','now')));
CREATE TABLE captures(
  id INTEGER PRIMARY KEY,
  session_id INTEGER NOT NULL REFERENCES sessions(id),
  idx INTEGER NOT NULL,
  expression TEXT NOT NULL,
  state TEXT NOT NULL DEFAULT 'pending'
    CHECK(state IN ('pending','capturing','rejected','done')),
  attempts INTEGER NOT NULL DEFAULT 0,
  qa_json TEXT NOT NULL DEFAULT '{}',
  frame_count INTEGER NOT NULL DEFAULT 0,
  frames_file_id INTEGER REFERENCES files(id),
  fused_file_id INTEGER REFERENCES files(id),
  completed_at TEXT,
  UNIQUE(session_id, idx),
  CHECK(state <> 'done' OR frames_file_id IS NOT NULL));
CREATE TABLE frames(
  id INTEGER PRIMARY KEY,
  capture_id INTEGER NOT NULL REFERENCES captures(id),
  seq INTEGER NOT NULL,
  depth_host_time_s REAL NOT NULL,
  color_host_time_s REAL NOT NULL,
  depth_device_ts INTEGER NOT NULL,
  color_device_ts INTEGER NOT NULL,
  file_id INTEGER NOT NULL REFERENCES files(id),
  offset INTEGER NOT NULL,             -- byte offset of the frame record in the file
  UNIQUE(capture_id, seq));
CREATE TABLE landmarks(
  id INTEGER PRIMARY KEY,
  capture_id INTEGER NOT NULL REFERENCES captures(id),
  source TEXT NOT NULL CHECK(source IN ('automatic','operator')),
  points_json TEXT NOT NULL,
  created_at TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ','now')),
  UNIQUE(capture_id, source));
CREATE TABLE meshes(
  id INTEGER PRIMARY KEY,
  session_id INTEGER NOT NULL REFERENCES sessions(id),
  capture_idx INTEGER,
  role TEXT NOT NULL CHECK(role IN ('fitted','neutral','scan')),
  name TEXT NOT NULL,
  vertex_count INTEGER NOT NULL,
  triangle_count INTEGER NOT NULL,
  file_id INTEGER NOT NULL REFERENCES files(id),
  created_at TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ','now')));
CREATE TABLE rigs(
  id INTEGER PRIMARY KEY,
  subject_id INTEGER NOT NULL REFERENCES subjects(id),
  session_id INTEGER REFERENCES sessions(id),
  shape_names_json TEXT NOT NULL,
  vertex_count INTEGER NOT NULL,
  triangle_count INTEGER NOT NULL,
  file_id INTEGER NOT NULL REFERENCES files(id),
  created_at TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ','now')));
CREATE TABLE models(
  id INTEGER PRIMARY KEY,
  kind TEXT NOT NULL,
  params_json TEXT NOT NULL DEFAULT '{}',
  file_id INTEGER NOT NULL REFERENCES files(id),
  created_at TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ','now')));
CREATE INDEX captures_by_session ON captures(session_id, idx);
CREATE INDEX meshes_by_session ON meshes(session_id);
)sql",
      // v2: tracking takes (the standalone tracking box records them per subject).
      R"sql(
CREATE TABLE takes(
  id INTEGER PRIMARY KEY,
  subject_id INTEGER NOT NULL REFERENCES subjects(id),
  session_id INTEGER REFERENCES sessions(id),
  fps REAL NOT NULL CHECK(fps > 0),
  shape_names_json TEXT NOT NULL,
  frame_count INTEGER NOT NULL,
  file_id INTEGER NOT NULL REFERENCES files(id),
  created_at TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ','now')));
)sql",
      // v3: takes keep each frame's time (TakeWriter, FBTAK002 files). time_source says where
      // an older take's times are: 'frame_rate' (frame / fps: the device's takes) or
      // 'last_column' (the host appended a "timestamp_s" pseudo-shape; its name is dropped here,
      // the column is read from the FBTAK001 file).
      R"sql(
ALTER TABLE takes ADD COLUMN time_source TEXT NOT NULL DEFAULT 'frame_rate'
  CHECK(time_source IN ('frame_rate','last_column','file'));
UPDATE takes SET time_source='last_column',
  shape_names_json=json_remove(shape_names_json, '$[#-1]')
  WHERE )sql" +
          std::string(kHostTimestampColumn) + ";",
  };
  return list;
}

// --- little binary helpers for the data files (all little-endian, see the static_assert)

class ByteWriter {
 public:
  template <class T>
  void put(T v) {
    const auto* p = reinterpret_cast<const std::uint8_t*>(&v);
    bytes.insert(bytes.end(), p, p + sizeof(T));
  }
  template <class T>
  void put_span(std::span<const T> v) {
    const auto* p = reinterpret_cast<const std::uint8_t*>(v.data());
    bytes.insert(bytes.end(), p, p + v.size_bytes());
  }
  void put_magic(const char (&magic)[9]) { bytes.insert(bytes.end(), magic, magic + 8); }
  std::vector<std::uint8_t> bytes;
};

class ByteReader {
 public:
  ByteReader(std::span<const std::uint8_t> bytes, std::size_t pos = 0) : bytes_(bytes), pos_(pos) {}
  template <class T>
  bool get(T& v) {
    if (bytes_.size() - pos_ < sizeof(T) || pos_ > bytes_.size()) return false;
    std::memcpy(&v, bytes_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return true;
  }
  template <class T>
  bool get_array(std::vector<T>& out, std::size_t count) {
    if (count > (bytes_.size() - pos_) / sizeof(T)) return false;
    out.resize(count);
    std::memcpy(out.data(), bytes_.data() + pos_, count * sizeof(T));
    pos_ += count * sizeof(T);
    return true;
  }
  bool magic(const char (&m)[9]) {
    if (bytes_.size() - pos_ < 8 || std::memcmp(bytes_.data() + pos_, m, 8) != 0) return false;
    pos_ += 8;
    return true;
  }
  bool at_end() const { return pos_ == bytes_.size(); }

 private:
  std::span<const std::uint8_t> bytes_;
  std::size_t pos_;
};

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

constexpr char kSeqMagic[9] = "FBSEQ001";
constexpr char kDepthMagic[9] = "FBDEP001";
constexpr char kMeshMagic[9] = "FBMSH001";
constexpr char kRigMagic[9] = "FBRIG001";
constexpr char kTakeMagicV1[9] = "FBTAK001";  // pose + weights, no times (before v3)
constexpr char kTakeMagic[9] = "FBTAK002";    // times (f64), then pose + weights (f32)

template <class Pixel>
bool read_image(ByteReader& reader, int w, int h, Image<Pixel>& out) {
  if (w < 0 || h < 0 || w > 16384 || h > 16384) return false;
  std::vector<std::uint8_t> raw;
  if (!reader.get_array(raw, static_cast<std::size_t>(w) * h * sizeof(Pixel))) return false;
  out.resize(w, h);
  if (!raw.empty()) std::memcpy(out.pixels.data(), raw.data(), raw.size());
  return true;
}

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

}  // namespace

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

// ---------------------------------------------------------------------------------------------

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

  // Best effort: removes data files whose commit failed (the orphan cleanup would get them
  // at the next open anyway).
  void discard(const std::vector<StoredFile>& files) const {
    for (const auto& f : files) {
      std::error_code ec;
      fs::remove(root / f.relpath, ec);
    }
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
  Result<std::vector<std::uint8_t>> load_file(std::int64_t file_id) const {
    auto f = data_file(file_id);
    if (!f) return f.failure();
    auto data = read_file_bytes(f->path);
    if (!data) return data.failure();
    if (data->size() != f->bytes || sha256_hex(*data) != f->sha256) return fail(damaged(*f));
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
  auto stmt =
      sql::prepare(impl_->db.get(), "SELECT id, name, created_at FROM subjects ORDER BY id");
  if (!stmt) return stmt.failure();
  std::vector<SubjectInfo> out;
  for (;;) {
    auto row = stmt->step();
    if (!row) return row.failure();
    if (!*row) break;
    out.push_back({stmt->int64(0), stmt->text(1), stmt->text(2)});
  }
  return out;
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
  const std::string folder = "sessions/" + std::to_string(id);
  auto update = sql::prepare(db, "UPDATE sessions SET folder=? WHERE id=?");
  if (!update) return update.failure();
  update->bind_all(folder, id);
  if (auto r = update->run(); !r) return r.failure();
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
  auto stmt =
      sql::prepare(impl_->db.get(),
                   "SELECT s.id, s.subject_id, s.created_at, s.state, s.folder, "
                   "(SELECT count(*) FROM captures c WHERE c.session_id=s.id), "
                   "(SELECT count(*) FROM captures c WHERE c.session_id=s.id AND c.state='done') "
                   "FROM sessions s ORDER BY s.id");
  if (!stmt) return stmt.failure();
  std::vector<SessionInfo> out;
  for (;;) {
    auto row = stmt->step();
    if (!row) return row.failure();
    if (!*row) break;
    SessionInfo s;
    s.id = stmt->int64(0);
    s.subject = stmt->int64(1);
    s.created_at = stmt->text(2);
    s.complete = stmt->text(3) == "complete";
    s.folder = impl_->root / stmt->text(4);
    s.capture_count = stmt->int32(5);
    s.done_count = stmt->int32(6);
    out.push_back(std::move(s));
  }
  return out;
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

namespace {

// A capture's .fbseq file, streamed frame by frame (a capture is tens of megabytes), with what
// the frames table needs: each frame's header and byte offset.
struct FrameSequence {
  SessionStore::Impl::StoredFile file;
  std::vector<std::uint64_t> offsets;
  std::vector<frame_record::Header> headers;
};

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

}  // namespace

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
  // Decodes the sequence; on a short or inconsistent file the checksum decides whether it is
  // damaged (changed after the commit) or malformed (written wrong).
  auto decode = [&]() -> Result<void> {
    char magic[8];
    std::uint32_t count = 0, reserved = 0;
    if (!in.read(magic, 8) || std::memcmp(magic, kSeqMagic, 8) != 0 || !in.read(&count, 4) ||
        !in.read(&reserved, 4))
      return fail(bad);
    if (static_cast<int>(count) != c->frame_count) return fail(bad + " (frame count differs)");
    const std::size_t keep = std::min<std::size_t>(count, options.max_frames);
    out.frames.resize(keep);
    auto source = [&](void* data, std::size_t size) { return in.read(data, size); };
    for (std::uint32_t i = 0; i < count; ++i) {
      frame_record::Header h{};
      if (!in.read(&h, sizeof h) || !frame_record::plausible(h)) return fail(bad);
      const std::uint64_t n = frame_record::pixel_bytes(h);
      if (in.position() > file->bytes || n > file->bytes - in.position()) return fail(bad);
      const bool decoded = i < keep ? frame_record::read_pixels(h, out.frames[i], source)
                                    : in.skip(static_cast<std::size_t>(n));
      if (!decoded) return fail(bad);
    }
    if (in.position() != file->bytes) return fail(bad + " (trailing bytes)");
    return success();
  };
  auto decoded = decode();
  if (!in.matches(file->bytes, file->sha256)) return fail(Impl::damaged(*file));
  if (!decoded) return decoded.failure();
  if (fused_file) {
    auto fused = impl_->load_file(*fused_file);
    if (!fused) return fused.failure();
    ByteReader r(*fused);
    std::int32_t w = 0, h = 0;
    if (!r.magic(kDepthMagic) || !r.get(w) || !r.get(h) || !read_image(r, w, h, out.fused_depth) ||
        !r.at_end()) {
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
  if (auto r = impl_->require_writer(); !r) return r.failure();
  if (auto r = check_mesh(mesh, "mesh '" + name + "'"); !r) return r.failure();
  auto folder = impl_->session_folder(session);
  if (!folder) return folder.failure();
  ByteWriter w;
  w.put_magic(kMeshMagic);
  w.put(static_cast<std::uint32_t>(mesh.vertex_count()));
  w.put(static_cast<std::uint32_t>(mesh.triangle_count()));
  w.put_span(std::span<const float>(mesh.positions));
  w.put_span(std::span<const std::uint32_t>(mesh.triangles));
  auto file = impl_->write_data_file(*folder, "mesh.fbmsh", w.bytes);
  if (!file) return file.failure();
  sqlite3* db = impl_->db.get();
  auto insert = [&]() -> Result<MeshId> {
    auto tx = sql::Transaction::begin(db);
    if (!tx) return tx.failure();
    auto id = impl_->insert_file_row(*file);
    if (!id) return id.failure();
    auto stmt = sql::prepare(db,
                             "INSERT INTO meshes(session_id, capture_idx, role, name, "
                             "vertex_count, triangle_count, file_id) VALUES(?,?,?,?,?,?,?)");
    if (!stmt) return stmt.failure();
    stmt->bind_all(session,
                   capture_index ? std::optional<std::int64_t>(*capture_index) : std::nullopt,
                   to_string(role), name, mesh.vertex_count(), mesh.triangle_count(), *id);
    if (auto r = stmt->run(); !r) return r.failure();
    const MeshId mesh_id = sqlite3_last_insert_rowid(db);
    if (auto r = tx->commit(); !r) return r.failure();
    return mesh_id;
  };
  auto id = insert();
  if (!id) impl_->discard({*file});
  return id;
}

Result<std::vector<MeshInfo>> SessionStore::meshes(SessionId session) const {
  auto stmt = sql::prepare(impl_->db.get(),
                           "SELECT id, session_id, capture_idx, role, name, vertex_count, "
                           "triangle_count FROM meshes WHERE session_id=? ORDER BY id");
  if (!stmt) return stmt.failure();
  stmt->bind(1, session);
  std::vector<MeshInfo> out;
  for (;;) {
    auto row = stmt->step();
    if (!row) return row.failure();
    if (!*row) break;
    MeshInfo m;
    m.id = stmt->int64(0);
    m.session = stmt->int64(1);
    if (!stmt->is_null(2)) m.capture_index = stmt->int32(2);
    m.role = mesh_role_from(stmt->text(3));
    m.name = stmt->text(4);
    m.vertex_count = stmt->int32(5);
    m.triangle_count = stmt->int32(6);
    out.push_back(std::move(m));
  }
  return out;
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
  ByteReader r(*bytes);
  std::uint32_t nv = 0, nt = 0;
  MeshData mesh;
  if (!r.magic(kMeshMagic) || !r.get(nv) || !r.get(nt) ||
      !r.get_array(mesh.positions, std::size_t{3} * nv) ||
      !r.get_array(mesh.triangles, std::size_t{3} * nt) || !r.at_end()) {
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
  sqlite3* db = impl_->db.get();
  auto insert = [&]() -> Result<RigId> {
    auto tx = sql::Transaction::begin(db);
    if (!tx) return tx.failure();
    auto id = impl_->insert_file_row(*file);
    if (!id) return id.failure();
    auto stmt = sql::prepare(db,
                             "INSERT INTO rigs(subject_id, session_id, shape_names_json, "
                             "vertex_count, triangle_count, file_id) VALUES(?,?,?,?,?,?)");
    if (!stmt) return stmt.failure();
    stmt->bind_all(subject, session, names_to_json(rig.shape_names), rig.vertex_count(),
                   static_cast<int>(rig.triangles.size() / 3), *id);
    if (auto r = stmt->run(); !r) return r.failure();
    const RigId rig_id = sqlite3_last_insert_rowid(db);
    if (auto r = tx->commit(); !r) return r.failure();
    return rig_id;
  };
  auto id = insert();
  if (!id) impl_->discard({*file});
  return id;
}

Result<std::vector<RigInfo>> SessionStore::rigs(SubjectId subject) const {
  auto stmt = sql::prepare(impl_->db.get(),
                           "SELECT id, subject_id, session_id, shape_names_json, vertex_count, "
                           "triangle_count, created_at FROM rigs WHERE subject_id=? "
                           "ORDER BY id DESC");
  if (!stmt) return stmt.failure();
  stmt->bind(1, subject);
  std::vector<RigInfo> out;
  for (;;) {
    auto row = stmt->step();
    if (!row) return row.failure();
    if (!*row) break;
    RigInfo info;
    info.id = stmt->int64(0);
    info.subject = stmt->int64(1);
    info.session = stmt->optional_int64(2);
    info.shape_names = names_from_json(stmt->text(3));
    info.vertex_count = stmt->int32(4);
    info.triangle_count = stmt->int32(5);
    info.created_at = stmt->text(6);
    out.push_back(std::move(info));
  }
  return out;
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

Result<RigData> SessionStore::read_rig(RigId id) const {
  auto stmt =
      sql::prepare(impl_->db.get(), "SELECT file_id, shape_names_json FROM rigs WHERE id=?");
  if (!stmt) return stmt.failure();
  stmt->bind(1, id);
  auto row = stmt->step();
  if (!row) return row.failure();
  if (!*row) return fail("there is no rig " + std::to_string(id) + " in this store");
  RigData rig;
  rig.shape_names = names_from_json(stmt->text(1));
  auto bytes = impl_->load_file(stmt->int64(0));
  if (!bytes) return bytes.failure();
  ByteReader r(*bytes);
  std::uint32_t nv = 0, nt = 0, ns = 0;
  const Failure bad = fail("the file of rig " + std::to_string(id) + " is malformed");
  if (!r.magic(kRigMagic) || !r.get(nv) || !r.get(nt) || !r.get(ns) ||
      ns != rig.shape_names.size() || !r.get_array(rig.neutral, std::size_t{3} * nv)) {
    return bad;
  }
  rig.shapes.resize(ns);
  for (auto& s : rig.shapes) {
    if (!r.get_array(s, std::size_t{3} * nv)) return bad;
  }
  if (!r.get_array(rig.triangles, std::size_t{3} * nt) || !r.at_end()) return bad;
  return rig;
}

Result<ModelId> SessionStore::add_model(const std::string& kind, const std::string& params_json,
                                        std::span<const std::uint8_t> bytes) {
  if (auto r = impl_->require_writer(); !r) return r.failure();
  auto file = impl_->write_data_file("models", kind + ".bin", bytes);
  if (!file) return file.failure();
  sqlite3* db = impl_->db.get();
  auto insert = [&]() -> Result<ModelId> {
    auto tx = sql::Transaction::begin(db);
    if (!tx) return tx.failure();
    auto id = impl_->insert_file_row(*file);
    if (!id) return id.failure();
    auto stmt = sql::prepare(db, "INSERT INTO models(kind, params_json, file_id) VALUES(?,?,?)");
    if (!stmt) return stmt.failure();
    stmt->bind_all(kind, params_json, *id);
    if (auto r = stmt->run(); !r) return r.failure();
    const ModelId model_id = sqlite3_last_insert_rowid(db);
    if (auto r = tx->commit(); !r) return r.failure();
    return model_id;
  };
  auto id = insert();
  if (!id) impl_->discard({*file});
  return id;
}

Result<std::vector<ModelInfo>> SessionStore::models() const {
  auto stmt = sql::prepare(impl_->db.get(),
                           "SELECT m.id, m.kind, m.params_json, f.bytes, m.created_at FROM models "
                           "m JOIN files f ON f.id=m.file_id ORDER BY m.id");
  if (!stmt) return stmt.failure();
  std::vector<ModelInfo> out;
  for (;;) {
    auto row = stmt->step();
    if (!row) return row.failure();
    if (!*row) break;
    out.push_back({stmt->int64(0), stmt->text(1), stmt->text(2), stmt->int64(3), stmt->text(4)});
  }
  return out;
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
  w.put_magic(kTakeMagic);
  w.put(static_cast<std::uint32_t>(info.frame_count));
  w.put(static_cast<std::uint32_t>(info.stride()));
  w.put_span(std::span<const double>(take.times_s));
  w.put_span(std::span<const float>(take.values));
  auto file =
      impl_->write_data_file("subjects/" + std::to_string(info.subject), "take.fbtak", w.bytes);
  if (!file) return file.failure();
  sqlite3* db = impl_->db.get();
  auto insert = [&]() -> Result<TakeId> {
    auto tx = sql::Transaction::begin(db);
    if (!tx) return tx.failure();
    auto id = impl_->insert_file_row(*file);
    if (!id) return id.failure();
    auto stmt = sql::prepare(db,
                             "INSERT INTO takes(subject_id, session_id, fps, shape_names_json, "
                             "frame_count, file_id, time_source) VALUES(?,?,?,?,?,?,'file')");
    if (!stmt) return stmt.failure();
    stmt->bind_all(info.subject, info.session, info.fps, names_to_json(info.shape_names),
                   info.frame_count, *id);
    if (auto r = stmt->run(); !r) return r.failure();
    const TakeId take_id = sqlite3_last_insert_rowid(db);
    if (auto r = tx->commit(); !r) return r.failure();
    return take_id;
  };
  auto id = insert();
  if (!id) impl_->discard({*file});
  return id;
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

// Decodes a take file into `take` (whose info is set). FBTAK002 holds the times; an FBTAK001
// file from before schema v3 has none ('frame_rate': frame / fps) or has them as its last
// column ('last_column', the host's "timestamp_s" pseudo-shape).
bool decode_take(std::span<const std::uint8_t> bytes, const std::string& time_source,
                 TakeData& take) {
  ByteReader r(bytes);
  std::uint32_t frames = 0, stride = 0;
  const auto want = static_cast<std::uint32_t>(take.info.stride());
  if (time_source == "file") {
    return r.magic(kTakeMagic) && r.get(frames) && r.get(stride) && stride == want &&
           static_cast<int>(frames) == take.info.frame_count && r.get_array(take.times_s, frames) &&
           r.get_array(take.values, std::size_t{frames} * stride) && r.at_end();
  }
  const bool last_column = time_source == "last_column";
  std::vector<float> stored;
  if (!r.magic(kTakeMagicV1) || !r.get(frames) || !r.get(stride) ||
      stride != want + (last_column ? 1 : 0) || static_cast<int>(frames) != take.info.frame_count ||
      !r.get_array(stored, std::size_t{frames} * stride) || !r.at_end())
    return false;
  take.times_s.resize(frames);
  take.values.clear();
  take.values.reserve(std::size_t{frames} * want);
  for (std::uint32_t f = 0; f < frames; ++f) {
    const float* row = stored.data() + std::size_t{f} * stride;
    take.values.insert(take.values.end(), row, row + want);
    take.times_s[f] = last_column ? row[want] : f / take.info.fps;
  }
  return true;
}

}  // namespace

Result<std::vector<TakeInfo>> SessionStore::takes(SubjectId subject) const {
  auto stmt = sql::prepare(impl_->db.get(),
                           take_columns(impl_->schema_version) + "WHERE subject_id=? ORDER BY id");
  if (!stmt) return stmt.failure();
  stmt->bind(1, subject);
  std::vector<TakeInfo> out;
  for (;;) {
    auto row = stmt->step();
    if (!row) return row.failure();
    if (!*row) break;
    out.push_back(take_from_row(*stmt));
  }
  return out;
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
