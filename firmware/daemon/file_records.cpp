// The plain-file SessionRecords: one JSON document per session plus image files, each written
// to a temporary name, fsynced and renamed (then the directory fsynced), so a power cut leaves
// either the old or the new document. Frames are kept as the frontal (first) frame only; the
// SQLite store keeps every frame.
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "firmware/daemon/record_files.hpp"
#include "firmware/daemon/session_records.hpp"

namespace fb {
namespace fs = std::filesystem;
using nlohmann::json;

const char* to_string(RecordState state) {
  switch (state) {
    case RecordState::kPending:
      return "pending";
    case RecordState::kCapturing:
      return "capturing";
    case RecordState::kRejected:
      return "rejected";
    case RecordState::kDone:
      return "done";
  }
  return "?";
}

namespace {
using records::Fd;
using records::now_iso;
using records::pgm16;
using records::ppm;
using records::write_durable;

Result<json> read_json(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return fail("cannot read '" + path.string() + "'");
  std::ostringstream text;
  text << in.rdbuf();
  json doc = json::parse(text.str(), nullptr, false);
  if (doc.is_discarded()) return fail("'" + path.string() + "' is not valid JSON");
  return doc;
}

RecordState parse_state(const std::string& s) {
  for (auto st :
       {RecordState::kPending, RecordState::kCapturing, RecordState::kRejected, RecordState::kDone})
    if (s == to_string(st)) return st;
  return RecordState::kPending;
}

std::string capture_prefix(int index) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "capture-%02d", index);
  return buf;
}

class FileRecords : public SessionRecords {
 public:
  explicit FileRecords(fs::path root) : root_(std::move(root)) {}

  std::string backend() const override { return "files"; }
  fs::path root() const override { return root_; }

  Result<void> init() {
    std::error_code ec;
    fs::create_directories(root_ / "sessions", ec);
    if (ec) return fail("cannot create '" + (root_ / "sessions").string() + "': " + ec.message());
    if (fs::exists(root_ / "subjects.json")) {
      auto doc = read_json(root_ / "subjects.json");
      if (!doc) return doc.failure();
      subjects_ = *doc;
    } else {
      subjects_ = json::array();
    }
    return success();
  }

  Result<std::int64_t> add_subject(const std::string& name) override {
    const std::int64_t id = static_cast<std::int64_t>(subjects_.size()) + 1;
    subjects_.push_back({{"id", id}, {"name", name}, {"created_at", now_iso()}});
    if (auto ok = write_durable(root_ / "subjects.json", subjects_.dump(1)); !ok)
      return ok.failure();
    return id;
  }

  Result<std::int64_t> create_session(std::int64_t subject,
                                      const std::vector<std::string>& guide) override {
    auto all = sessions();
    if (!all) return all.failure();
    const std::int64_t id = all->empty() ? 1 : all->back().id + 1;
    json doc = {{"id", id}, {"subject", subject}, {"created_at", now_iso()}};
    json caps = json::array();
    for (std::size_t i = 0; i < guide.size(); ++i)
      caps.push_back({{"index", i},
                      {"expression", guide[i]},
                      {"state", "pending"},
                      {"attempts", 0},
                      {"qa", json::object()},
                      {"frame_count", 0},
                      {"completed_at", ""}});
    doc["captures"] = caps;
    std::error_code ec;
    fs::create_directories(folder(id), ec);
    if (ec) return fail("cannot create '" + folder(id).string() + "': " + ec.message());
    if (auto ok = save(id, doc); !ok) return ok.failure();
    return id;
  }

  Result<std::vector<RecordSession>> sessions() override {
    std::vector<RecordSession> out;
    std::error_code ec;
    for (const auto& entry : fs::directory_iterator(root_ / "sessions", ec)) {
      const std::string name = entry.path().filename().string();
      if (name.find_first_not_of("0123456789") != std::string::npos || name.empty()) continue;
      auto s = session(std::stoll(name));
      if (s) out.push_back(*s);
    }
    std::sort(out.begin(), out.end(), [](auto& a, auto& b) { return a.id < b.id; });
    return out;
  }

  Result<RecordSession> session(std::int64_t id) override {
    auto doc = load(id);
    if (!doc) return doc.failure();
    RecordSession s;
    s.id = id;
    s.subject = (*doc)["subject"].get<std::int64_t>();
    for (const auto& subj : subjects_)
      if (subj["id"] == s.subject) s.subject_name = subj["name"];
    s.created_at = (*doc)["created_at"];
    s.capture_count = static_cast<int>((*doc)["captures"].size());
    for (const auto& c : (*doc)["captures"]) s.done_count += c["state"] == "done" ? 1 : 0;
    s.complete = s.done_count == s.capture_count;
    s.folder = folder(id);
    return s;
  }

  Result<std::vector<RecordCapture>> captures(std::int64_t session) override {
    auto doc = load(session);
    if (!doc) return doc.failure();
    std::vector<RecordCapture> out;
    for (const auto& c : (*doc)["captures"]) {
      RecordCapture rc;
      rc.index = c["index"];
      rc.expression = c["expression"];
      rc.state = parse_state(c["state"]);
      rc.attempts = c["attempts"];
      rc.qa_scores = c["qa"].get<std::map<std::string, double>>();
      rc.frame_count = c["frame_count"];
      rc.completed_at = c["completed_at"];
      out.push_back(std::move(rc));
    }
    return out;
  }

  Result<void> begin_capture(std::int64_t session, int index) override {
    return update(session, index, [](json& c) {
      c["state"] = "capturing";
      c["attempts"] = c["attempts"].get<int>() + 1;
      return success();
    });
  }

  Result<void> reject_capture(std::int64_t session, int index,
                              const std::map<std::string, double>& qa) override {
    return update(session, index, [&](json& c) {
      c["state"] = "rejected";
      c["qa"] = qa;
      return success();
    });
  }

  Result<void> commit_capture(std::int64_t session, int index, CaptureCommit commit) override {
    const fs::path base = folder(session) / capture_prefix(index);
    // Data files first, then the document that references them: a crash in between leaves
    // files nobody references and the capture still not done.
    if (!commit.fused_depth.empty())
      if (auto ok = write_durable(base.string() + "-fused.pgm", pgm16(commit.fused_depth)); !ok)
        return ok;
    if (commit.frame_count() > 0) {
      RgbdFrame first;
      if (auto ok = commit.frames->read(0, first); !ok) return ok;
      if (auto ok = write_durable(base.string() + "-frame0-depth.pgm", pgm16(first.depth_mm)); !ok)
        return ok;
      if (!first.color.empty())
        if (auto ok = write_durable(base.string() + "-frame0-color.ppm", ppm(first.color)); !ok)
          return ok;
    }
    return update(session, index, [&](json& c) {
      c["state"] = "done";
      c["qa"] = commit.qa_scores;
      c["frame_count"] = commit.frame_count();
      c["completed_at"] = now_iso();
      return success();
    });
  }

  Result<fs::path> export_session(
      std::int64_t id, const fs::path& exports_dir,
      const std::function<bool()>& /*cancelled: unused, this export is a few small files*/)
      override {
    auto doc = load(id);
    if (!doc) return doc.failure();
    auto s = session(id);
    if (!s) return s.failure();
    const fs::path out = exports_dir / ("session-" + std::to_string(id));
    std::error_code ec;
    fs::create_directories(out, ec);
    if (ec) return fail("cannot create '" + out.string() + "': " + ec.message());
    json manifest = {{"format", "facebooth-session-export"},
                     {"version", 1},
                     {"session", id},
                     {"subject", s->subject_name},
                     {"complete", s->complete},
                     {"captures", (*doc)["captures"]}};
    for (auto& c : manifest["captures"]) {
      const int index = c["index"];
      const fs::path fused = folder(id) / (capture_prefix(index) + "-fused.pgm");
      if (c["state"] == "done" && fs::exists(fused)) {
        const std::string name =
            capture_prefix(index) + "-" + c["expression"].get<std::string>() + "-fused.pgm";
        fs::copy_file(fused, out / name, fs::copy_options::overwrite_existing, ec);
        if (ec) return fail("cannot copy '" + fused.string() + "': " + ec.message());
        c["fused_depth"] = name;
      }
    }
    if (auto ok = write_durable(out / "manifest.json", manifest.dump(1)); !ok) return ok.failure();
    return out;
  }

 private:
  fs::path folder(std::int64_t id) const { return root_ / "sessions" / std::to_string(id); }
  Result<json> load(std::int64_t id) {
    if (!fs::exists(folder(id) / "session.json"))
      return fail("session " + std::to_string(id) + " does not exist");
    return read_json(folder(id) / "session.json");
  }
  Result<void> save(std::int64_t id, const json& doc) {
    return write_durable(folder(id) / "session.json", doc.dump(1));
  }
  template <class F>
  Result<void> update(std::int64_t session, int index, F&& change) {
    auto doc = load(session);
    if (!doc) return doc.failure();
    auto& caps = (*doc)["captures"];
    if (index < 0 || index >= static_cast<int>(caps.size()))
      return fail("session " + std::to_string(session) + " has no capture " +
                  std::to_string(index));
    if (auto ok = change(caps[static_cast<std::size_t>(index)]); !ok) return ok;
    return save(session, *doc);
  }

  fs::path root_;
  json subjects_;
};

}  // namespace

Result<std::unique_ptr<SessionRecords>> open_file_records(const fs::path& data_dir) {
  auto records = std::make_unique<FileRecords>(data_dir / "file-store");
  if (auto ok = records->init(); !ok) return ok.failure();
  return std::unique_ptr<SessionRecords>(std::move(records));
}

// The base class's answers for stores that keep only captures (the file store).
namespace {
Error unsupported(const SessionRecords& r, const char* what) {
  return Error{"the '" + r.backend() + "' session store does not keep " + what +
               " (build faceboothd with storage/'s SQLite SessionStore)"};
}
}  // namespace

Result<void> SessionRecords::add_fit(std::int64_t, int, const FitRecord&) {
  return fail(unsupported(*this, "fitted meshes"));
}
Result<std::optional<MeshData>> SessionRecords::neutral_mesh(std::int64_t) {
  return std::optional<MeshData>{};
}
Result<void> SessionRecords::set_operator_landmarks(std::int64_t, int,
                                                    const std::vector<Landmark>&) {
  return fail(unsupported(*this, "landmark corrections"));
}
Result<std::int64_t> SessionRecords::add_take(const TakeRecord&, std::span<const float>) {
  return fail(unsupported(*this, "tracking takes"));
}
Result<OffloadInfo> SessionRecords::offload_info(std::int64_t) {
  return OffloadInfo{};
}
Result<std::int64_t> SessionRecords::add_rig(std::int64_t, const RigData&) {
  return fail(unsupported(*this, "rigs"));
}
Result<std::optional<StoredRig>> SessionRecords::subject_rig(std::int64_t) {
  return std::optional<StoredRig>{};
}

}  // namespace fb
