// The session store: subjects, capture sessions, captures, frames, landmarks, meshes, rigs,
// models and tracking takes, in one SQLite database plus per-session folders of immutable data
// files (see storage/README.md for the layout, the crash-safety protocol and the thread model).
//
// Thread model: one SessionStore opened as the writer (a process-wide exclusive lock file makes
// a second writer fail with a clear error) used from one thread; any number of read-only stores
// (open with StoreOptions::read_only), each on its own thread with its own connection. WAL mode
// means readers never block the writer and see only committed rows. A SessionStore object itself
// is not thread-safe: do not share one between threads.
//
// Every call returns Result<T>; nothing throws out of this API.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "algo/core/frame.hpp"
#include "algo/core/image.hpp"
#include "algo/core/result.hpp"
#include "storage/stored_data.hpp"

namespace fb {

inline constexpr int kSessionStoreSchemaVersion = 7;
inline constexpr const char* kSessionStoreDatabaseName = "facebooth.db";

using SubjectId = std::int64_t;
using SessionId = std::int64_t;
using MeshId = std::int64_t;
using RigId = std::int64_t;
using ModelId = std::int64_t;
using TakeId = std::int64_t;
using TextureId = std::int64_t;

enum class CaptureState {
  kPending,    // not started
  kCapturing,  // started (attempts counted), nothing committed yet
  kRejected,   // the last attempt failed QA; must be captured again
  kDone,       // frames, fused depth, landmarks and QA scores are committed
};
const char* to_string(CaptureState state);

enum class MeshRole {
  kFitted,   // a fitted expression mesh (FaceWarehouse's TrainingPose)
  kNeutral,  // the fitted neutral
  kScan,     // a fused scan turned into a mesh
};
const char* to_string(MeshRole role);

// Where the store's work is, reported through StoreOptions::on_phase (crash tests use it to tell
// where a kill landed).
enum class StorePhase { kIdle, kWritingFile, kSyncingFile, kRenaming, kCommitting };

struct StoreOptions {
  bool read_only = false;  // a reader: own connection, no lock, no cleanup, no migrations
  bool create = true;      // writer only: create the store when the folder/database is missing

  // Test hooks; leave empty in production.
  // Called before every write(2) of a data file with the bytes of that file written so far; a
  // non-zero return is used as the errno of a failed write (ENOSPC simulates a full disk).
  std::function<int(std::size_t bytes_written)> inject_write_error;
  std::function<void(StorePhase)> on_phase;
  int migrate_to = 0;  // apply migrations only up to this version (0 = all)
};

struct SubjectInfo {
  SubjectId id = 0;
  std::string name;
  std::string created_at;  // ISO 8601 UTC
};

struct SessionInfo {
  SessionId id = 0;
  SubjectId subject = 0;
  std::string created_at;
  bool complete = false;  // every capture is done
  int capture_count = 0;
  int done_count = 0;
  std::filesystem::path folder;  // absolute path of the session's data folder
  // The unit calibration its frames were taken with (device.json text); empty when the device
  // did not record one (stores before schema v4): the host then assumes the defaults.
  std::string calibration_json;
  // Where an imported session came from (`facebooth sync`, schema v5): the booth's id and the
  // session's id on that booth; empty / 0 for a session captured into this store.
  std::string origin_booth;
  std::int64_t origin_session = 0;
};

struct CaptureInfo {
  std::int64_t id = 0;
  SessionId session = 0;
  int index = 0;           // position in the guide sequence, 0-based
  std::string expression;  // guide expression name
  CaptureState state = CaptureState::kPending;
  int attempts = 0;  // begin_capture calls so far
  std::map<std::string, double> qa_scores;
  int frame_count = 0;
  std::string completed_at;  // empty unless done
};

// What the device hands over when a capture passed QA.
struct CaptureInput {
  std::vector<RgbdFrame> frames;  // the head-turn sequence as the camera delivered it
  // Or, when `frames` is empty, `frame_count` frames read one at a time in order from a source
  // (the device keeps a take's frames on disk, not in memory).
  std::size_t frame_count = 0;
  std::function<Result<void>(std::size_t index, RgbdFrame& out)> read_frame;
  DepthImage fused_depth;           // the fused frontal depth map (may be empty)
  std::vector<Landmark> landmarks;  // automatic landmarks (may be empty)
  std::map<std::string, double> qa_scores;
};

// What read_capture decodes. The whole frame file is always read and checked against its
// committed SHA-256; only the first `max_frames` frames are kept in memory (an export needs the
// first colour frame, not a 45 MB sequence on a 256 MB device).
struct CaptureReadOptions {
  std::size_t max_frames = static_cast<std::size_t>(-1);
};

struct CaptureData {
  CaptureInfo info;               // info.frame_count is the stored count
  std::vector<RgbdFrame> frames;  // the first min(frame_count, max_frames) frames
  DepthImage fused_depth;
  std::vector<Landmark> landmarks;  // the operator's correction when present, else automatic
  LandmarkSource landmark_source = LandmarkSource::kAutomatic;
};

// A texture atlas in the face model's UV layout (PNG): the session's subject texture
// (capture_index empty) or one capture's expression texture.
struct TextureInfo {
  TextureId id = 0;
  SessionId session = 0;
  std::optional<int> capture_index;
  int width = 0;
  int height = 0;
  std::string params_json;  // how it was built (views, coverage), free JSON
  std::int64_t bytes = 0;
  std::string created_at;
};

// One capture's wrinkle detail in the face model's UV layout (schema v6, `facebooth wrinkles`):
// a displacement map (mm along the surface normal, + outwards, 0 where nothing was synthesised)
// and its tangent-space normal map (x along +u, y along +v, PNG).
using WrinkleDetailId = std::int64_t;
struct WrinkleDetailInfo {
  WrinkleDetailId id = 0;
  SessionId session = 0;
  int capture_index = 0;
  std::optional<RigId> rig;  // the rig serving the session when the detail was made
  int width = 0;
  int height = 0;
  std::string params_json;  // how it was built (regions, texels with detail), free JSON
  std::string created_at;
};
struct WrinkleDetailData {
  int width = 0;
  int height = 0;
  std::vector<float> displacement_mm;  // width * height, row-major, row 0 at the top
  std::vector<std::uint8_t> normal_png;
};

struct MeshInfo {
  MeshId id = 0;
  SessionId session = 0;
  std::optional<int> capture_index;
  MeshRole role = MeshRole::kFitted;
  std::string name;
  int vertex_count = 0;
  int triangle_count = 0;
};

struct MeshInput {
  std::optional<int> capture_index;
  MeshRole role = MeshRole::kFitted;
  std::string name;
  MeshData mesh;
};

struct RigInfo {
  RigId id = 0;
  SubjectId subject = 0;
  std::optional<SessionId> session;
  std::vector<std::string> shape_names;
  int vertex_count = 0;
  int triangle_count = 0;
  std::string created_at;
  std::vector<RigDetailCapture> detail_captures;  // RigData::detail_captures
};

struct ModelInfo {
  ModelId id = 0;
  std::string kind;         // e.g. "bilinear"
  std::string params_json;  // free-form description (dimensions, sources)
  std::int64_t bytes = 0;
  std::string created_at;
};

// A tracking take: per frame its time, the head pose (tx ty tz mm, then qx qy qz qw, a unit
// quaternion; camera_from_model) and one weight per shape. Written by TakeWriter
// (storage/take_writer.hpp), the one writer of takes for the host and the device.
inline constexpr int kTakePoseValues = 7;
struct TakeInfo {
  TakeId id = 0;
  SubjectId subject = 0;
  std::optional<SessionId> session;  // the session whose subject or rig was tracked
  double fps = 30.0;                 // the camera's nominal rate (the times are measured)
  std::vector<std::string> shape_names;
  int frame_count = 0;
  std::string created_at;
  int stride() const { return kTakePoseValues + static_cast<int>(shape_names.size()); }
};

struct TakeData {
  TakeInfo info;
  std::vector<double> times_s;  // per frame: seconds from the take's first frame
  std::vector<float> values;    // per frame: stride() values, the pose then the weights
  std::span<const float> frame(int f) const {
    const auto stride = static_cast<std::size_t>(info.stride());
    return std::span<const float>(values).subspan(static_cast<std::size_t>(f) * stride, stride);
  }
};

// A session fetched from a booth (`facebooth sync`, storage/bundle_import.hpp), imported in one
// transaction. The subject is keyed by (booth, origin_subject): a booth's later sessions of the
// same subject join it, and two booths never share a subject or a session by accident of ids.
struct ImportedCapture {
  int index = 0;
  std::string expression;
  CaptureState state = CaptureState::kPending;
  int attempts = 0;
  std::map<std::string, double> qa_scores;
  std::vector<RgbdFrame> frames;  // a done capture needs at least one
  DepthImage fused_depth;         // may be empty
  std::vector<Landmark> landmarks;
  LandmarkSource landmark_source = LandmarkSource::kAutomatic;
  std::optional<MeshData> mesh;  // the booth's newest fit of the capture
  MeshRole mesh_role = MeshRole::kFitted;
};

struct SessionImport {
  std::string booth;  // the booth's id ([A-Za-z0-9_-], 1..64 characters)
  std::int64_t origin_session = 0;
  std::int64_t origin_subject = 0;
  std::string subject_name;
  std::string calibration_json;           // the unit's device.json text, may be empty
  std::vector<ImportedCapture> captures;  // index 0..n-1, in order
};

// Result of SessionStore::verify().
struct VerifyReport {
  std::string integrity;  // PRAGMA integrity_check's answer, "ok" when healthy
  int files_checked = 0;
  std::vector<std::string> problems;  // missing or mismatching files, one line each
  bool ok() const { return integrity == "ok" && problems.empty(); }
};

class SessionStore {
 public:
  // Opens (and, for a writer, creates and migrates) the store in `root`: root/facebooth.db plus
  // data folders. A writer also deletes orphaned data files (written but never committed) and
  // temporary files left by a crash. Fails without touching anything when the database is from a
  // newer facebooth, is not a facebooth database, or is corrupt.
  static Result<SessionStore> open(const std::filesystem::path& root,
                                   const StoreOptions& options = {});

  SessionStore(SessionStore&&) noexcept;
  SessionStore& operator=(SessionStore&&) noexcept;
  ~SessionStore();

  const std::filesystem::path& root() const;
  int schema_version() const;
  bool read_only() const;
  // Data files removed by the orphan cleanup at open (0 for readers).
  int orphans_removed() const;

  // --- subjects and sessions
  Result<SubjectId> add_subject(const std::string& name);
  Result<std::vector<SubjectInfo>> subjects() const;
  Result<SubjectInfo> subject(SubjectId id) const;

  // A session with one pending capture per guide expression, in order.
  Result<SessionId> create_session(SubjectId subject, const std::vector<std::string>& guide);
  Result<SessionInfo> session(SessionId id) const;
  Result<std::vector<SessionInfo>> sessions() const;

  // --- captures
  Result<std::vector<CaptureInfo>> captures(SessionId session) const;
  Result<CaptureInfo> capture(SessionId session, int index) const;
  // Resume point: the first capture (in guide order) that is not done, or nullopt when the
  // session is complete.
  Result<std::optional<CaptureInfo>> next_capture(SessionId session) const;
  // Marks a capture as being captured and counts the attempt.
  Result<void> begin_capture(SessionId session, int index);
  // Marks the current attempt as failed QA (scores kept); next_capture() returns it again.
  Result<void> reject_capture(SessionId session, int index,
                              const std::map<std::string, double>& qa_scores);
  // Stores frames, fused depth, automatic landmarks and QA scores and marks the capture done, in
  // one durable step (data files written and fsynced first, then one synchronous=FULL commit).
  // A crash at any point leaves either the whole capture or none of it.
  Result<void> commit_capture(SessionId session, int index, const CaptureInput& input);
  // Reads a done capture back, verifying every data file's SHA-256.
  Result<CaptureData> read_capture(SessionId session, int index,
                                   const CaptureReadOptions& options = {}) const;
  // Stores (or replaces) the operator's landmark correction of a done capture.
  Result<void> set_operator_landmarks(SessionId session, int index,
                                      const std::vector<Landmark>& landmarks);

  // Records the unit calibration (device.json text) the session's frames are taken with.
  Result<void> set_session_calibration(SessionId session, const std::string& device_json);

  // --- sessions imported from booths (schema v5)
  // Stores a whole session (subject found or added, session, captures, frames, landmarks,
  // meshes) in one durable step: a failure or a crash at any point leaves none of it. Fails
  // when the session was imported before (imported_session() says as which).
  Result<SessionId> import_session(const SessionImport& session);
  // The local id of the booth's session when it has been imported (nullopt: not yet).
  Result<std::optional<SessionId>> imported_session(const std::string& booth,
                                                    std::int64_t origin_session) const;

  // --- meshes, rigs, models, takes
  Result<MeshId> add_mesh(SessionId session, std::optional<int> capture_index, MeshRole role,
                          const std::string& name, const MeshData& mesh);
  // Several meshes of a session in one durable step (all or none), e.g. a session's refit.
  Result<std::vector<MeshId>> add_meshes(SessionId session, const std::vector<MeshInput>& meshes);
  Result<std::vector<MeshInfo>> meshes(SessionId session) const;
  Result<MeshData> read_mesh(MeshId id) const;

  // Texture atlases (PNG bytes); textures() lists a session's oldest first.
  Result<TextureId> add_texture(SessionId session, std::optional<int> capture_index, int width,
                                int height, std::span<const std::uint8_t> png,
                                const std::string& params_json);
  Result<std::vector<TextureInfo>> textures(SessionId session) const;
  Result<std::vector<std::uint8_t>> read_texture(TextureId id) const;

  // Wrinkle detail maps (schema v6): both files written durably, then one row in one
  // transaction, so a crash leaves the whole detail or none of it. wrinkle_details() lists a
  // session's oldest first (a capture's newest detail is its last row).
  Result<WrinkleDetailId> add_wrinkle_detail(SessionId session, int capture_index,
                                             std::optional<RigId> rig,
                                             const WrinkleDetailData& detail,
                                             const std::string& params_json);
  Result<std::vector<WrinkleDetailInfo>> wrinkle_details(SessionId session) const;
  Result<WrinkleDetailData> read_wrinkle_detail(WrinkleDetailId id) const;

  Result<RigId> add_rig(SubjectId subject, std::optional<SessionId> session, const RigData& rig);
  Result<std::vector<RigInfo>> rigs(SubjectId subject) const;  // newest first
  // Checks the file's SHA-256 unless `verify_sha256` is false: for a caller reading the same
  // rig again in one run after a verified read (model build's passes); the size is checked.
  Result<RigData> read_rig(RigId id, bool verify_sha256 = true) const;
  // Which rig serves a session, the one rule for exports, model building, tracking and the
  // device: the newest rig built from this session, else the subject's newest rig (built from
  // another of their sessions, imported, or saved by `track --save-rig`). RigInfo::session says
  // which session built it. nullopt: the subject has no rig.
  Result<std::optional<RigInfo>> rig_for(SessionId session) const;
  // The rig serving a subject when no session is named: their newest (rig_for's fallback).
  Result<std::optional<RigInfo>> newest_rig(SubjectId subject) const;

  Result<ModelId> add_model(const std::string& kind, const std::string& params_json,
                            std::span<const std::uint8_t> bytes);
  Result<std::vector<ModelInfo>> models() const;
  Result<std::vector<std::uint8_t>> read_model(ModelId id) const;

  // Stores a take (TakeWriter::store is the way to call this): `take.values` holds
  // frame_count * stride() floats and `take.times_s` one time per frame.
  Result<TakeId> add_take(const TakeData& take);
  Result<std::vector<TakeInfo>> takes(SubjectId subject) const;
  // Reads a take back in the current layout, whichever layout it was stored in (takes from
  // before schema v3 get their times from the frame rate or from the "timestamp_s" column the
  // host used to append).
  Result<TakeData> read_take(TakeId id) const;

  // PRAGMA integrity_check plus existence, size and SHA-256 of every referenced data file.
  Result<VerifyReport> verify() const;

  struct Impl;

 private:
  explicit SessionStore(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace fb
