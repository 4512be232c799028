// What the kiosk session needs from storage, as one narrow interface over the one store, the
// SQLite SessionStore (storage/session_store.hpp, crash-safe commits; store_records.cpp). A
// capture is committed in one durable step, which is what makes resume after power loss
// possible. The interface stays so daemon tests and the state machine see storage through one
// seam. Not thread-safe: the daemon serialises calls.
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
#include "algo/core/result.hpp"
#include "firmware/daemon/frame_spool.hpp"
#include "storage/stored_data.hpp"
#include "storage/take_writer.hpp"

namespace fb {

enum class RecordState { kPending, kCapturing, kRejected, kDone };
const char* to_string(RecordState state);

struct RecordSession {
  std::int64_t id = 0;
  std::int64_t subject = 0;
  std::string subject_name;
  std::string created_at;
  bool complete = false;
  int capture_count = 0;
  int done_count = 0;
  std::filesystem::path folder;
};

struct RecordCapture {
  int index = 0;
  std::string expression;
  RecordState state = RecordState::kPending;
  int attempts = 0;
  std::map<std::string, double> qa_scores;
  int frame_count = 0;
  std::string completed_at;
};

struct CaptureCommit {
  std::unique_ptr<FrameSpool> frames;  // the stored frames of the take, on disk
  std::size_t frame_count() const { return frames ? frames->size() : 0; }
  DepthImage fused_depth;
  std::map<std::string, double> qa_scores;
  std::vector<Landmark> landmarks;  // automatic landmarks (colour px + lifted 3D), may be empty
  std::string calibration_json;     // the take camera's unit calibration (device.json text)
};

// A fitted mesh of a capture (the quick fit); the newest one of a capture wins.
struct FitRecord {
  bool neutral = false;  // the session's fitted neutral (capture 0)
  std::string name;      // the guide expression
  MeshData mesh;         // model frame, mm
};

// Whose tracking take it is; the frames are in a TakeWriter (storage/take_writer.hpp).
struct TakeRecord {
  std::int64_t session = 0;  // the session whose subject (and rig) was tracked (0 = none)
  std::string subject_name;  // used when there is no session
};

// What the host tool needs to know before fetching a session (offload).
struct OffloadInfo {
  int fitted_captures = 0;  // done captures with a fitted mesh
  int rigs = 0;             // rigs stored for the session's subject from this session
  std::vector<RigDetailCapture> rig_detail_captures;  // the newest of them's (RigData)
};

// A rig stored for a subject (uploaded by the host after rigging one of their sessions).
struct StoredRig {
  std::int64_t id = 0;
  std::int64_t subject = 0;
  RigData data;
};

class SessionRecords {
 public:
  virtual ~SessionRecords() = default;
  virtual std::string backend() const = 0;  // "sqlite" (reported in the status JSON)
  virtual std::filesystem::path root() const = 0;

  virtual Result<std::int64_t> add_subject(const std::string& name) = 0;
  virtual Result<std::int64_t> create_session(std::int64_t subject,
                                              const std::vector<std::string>& guide) = 0;
  virtual Result<std::vector<RecordSession>> sessions() = 0;  // oldest first
  virtual Result<RecordSession> session(std::int64_t id) = 0;
  virtual Result<std::vector<RecordCapture>> captures(std::int64_t session) = 0;
  virtual Result<void> begin_capture(std::int64_t session, int index) = 0;
  virtual Result<void> reject_capture(std::int64_t session, int index,
                                      const std::map<std::string, double>& qa) = 0;
  virtual Result<void> commit_capture(std::int64_t session, int index, CaptureCommit commit) = 0;
  // Writes (or rewrites) the session's export folder under `exports_dir` and returns it. When
  // `cancelled` turns true (the daemon is stopping) the export is abandoned between captures:
  // it is written to a temporary folder and renamed at the end, so nothing half-done remains.
  virtual Result<std::filesystem::path> export_session(
      std::int64_t id, const std::filesystem::path& exports_dir,
      const std::function<bool()>& cancelled = {}) = 0;

  // Fits, landmarks, takes and rigs.
  virtual bool keeps_fits() const = 0;  // reported as store_keeps_fits in the status JSON
  virtual Result<void> add_fit(std::int64_t session, int index, const FitRecord& fit) = 0;
  // The newest fitted neutral of a session (nullopt when there is none).
  virtual Result<std::optional<MeshData>> neutral_mesh(std::int64_t session) = 0;
  virtual Result<void> set_operator_landmarks(std::int64_t session, int index,
                                              const std::vector<Landmark>& landmarks) = 0;
  virtual Result<std::int64_t> add_take(const TakeRecord& take, TakeWriter& frames) = 0;
  virtual Result<OffloadInfo> offload_info(std::int64_t session) = 0;
  // Stores a rig uploaded by the host for the session's subject; returns its id.
  virtual Result<std::int64_t> add_rig(std::int64_t session, const RigData& rig) = 0;
  // The rig serving the session (SessionStore::rig_for; nullopt: the subject has none).
  virtual Result<std::optional<StoredRig>> rig_for(std::int64_t session) = 0;
};

// The SQLite session store under `data_dir` (storage/session_store).
Result<std::unique_ptr<SessionRecords>> open_session_records(const std::filesystem::path& data_dir);

}  // namespace fb
