// SessionRecords over the SQLite SessionStore (storage/session_store.hpp): the production
// store, with crash-safe commits of every frame, the fused depth and the QA scores.
#include <nlohmann/json.hpp>

#include "firmware/daemon/record_files.hpp"
#include "firmware/daemon/session_records.hpp"
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
  Result<void> commit_capture(std::int64_t session, int index, CaptureCommit commit) override {
    CaptureInput input;
    input.frames = std::move(commit.frames);
    input.fused_depth = std::move(commit.fused_depth);
    input.qa_scores = std::move(commit.qa_scores);
    return store_.commit_capture(session, index, input);
  }
  Result<fs::path> export_session(std::int64_t id, const fs::path& exports_dir) override {
    auto s = store_.session(id);
    if (!s) return s.failure();
    auto caps = store_.captures(id);
    if (!caps) return caps.failure();
    const fs::path out = exports_dir / ("session-" + std::to_string(id));
    std::error_code ec;
    fs::create_directories(out, ec);
    if (ec) return fail("cannot create '" + out.string() + "': " + ec.message());
    nlohmann::json list = nlohmann::json::array();
    for (const auto& c : *caps) {
      nlohmann::json j = {{"index", c.index},
                          {"expression", c.expression},
                          {"state", to_string(from_store(c.state))},
                          {"attempts", c.attempts},
                          {"qa", c.qa_scores},
                          {"frame_count", c.frame_count}};
      if (c.state == CaptureState::kDone) {
        auto data = store_.read_capture(id, c.index);
        if (!data) return data.failure();
        char name[96];
        std::snprintf(name, sizeof name, "capture-%02d-%s-fused.pgm", c.index,
                      c.expression.c_str());
        if (!data->fused_depth.empty()) {
          if (auto ok = records::write_durable(out / name, records::pgm16(data->fused_depth)); !ok)
            return ok.failure();
          j["fused_depth"] = name;
        }
      }
      list.push_back(std::move(j));
    }
    std::string subject_name;
    if (auto subj = store_.subject(s->subject)) subject_name = subj->name;
    nlohmann::json manifest = {{"format", "facebooth-session-export"},
                               {"version", 1},
                               {"session", id},
                               {"subject", subject_name},
                               {"complete", s->complete},
                               {"store", store_.root().string()},
                               {"captures", list}};
    if (auto ok = records::write_durable(out / "manifest.json", manifest.dump(1)); !ok)
      return ok.failure();
    return out;
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

  SessionStore store_;
};

}  // namespace

Result<std::unique_ptr<SessionRecords>> open_session_records(const fs::path& data_dir) {
  auto store = SessionStore::open(data_dir / "store");
  if (!store) return store.failure();
  return std::unique_ptr<SessionRecords>(std::make_unique<StoreRecords>(std::move(*store)));
}

}  // namespace fb
