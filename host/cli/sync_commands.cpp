// facebooth sync: collect the sessions of one or more booths into a host store, rig them, and
// send each rig back (the booth's tracking mode then tracks the subject with it).
//
// Per booth (one thread each, so booths transfer in parallel): GET /api/offload/ready; for each
// session ready for rigging that the host store has not imported (keyed by the booth's id and
// its session id), the bundle is downloaded into HOST_STORE/.sync/BOOTH/ (resumed after a cut),
// checked (storage/bundle_import: paths, every file's SHA-256 against the booth's manifest) and
// imported in one transaction; then rigged as `rig --save` does, and the rig uploaded unless the
// booth already has one from that session. The store is the one writer; its calls are serialised
// by a mutex, the downloads and the rigging run outside it. JSON report on stdout, progress on
// stderr.
#include <signal.h>

#include <chrono>
#include <ctime>
#include <filesystem>
#include <iostream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <thread>

#include "algo/core/clock.hpp"
#include "host/cli/booth_client.hpp"
#include "host/cli/commands.hpp"
#include "host/cli/detail_weights.hpp"
#include "host/cli/guide_files.hpp"
#include "host/cli/progress.hpp"
#include "host/cli/rig_session.hpp"
#include "host/cli/rig_support.hpp"
#include "storage/asset_files.hpp"
#include "storage/bundle_import.hpp"
#include "storage/durable_file.hpp"
#include "storage/export/facewarehouse.hpp"
#include "storage/session_store.hpp"

namespace fb::cli {

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// The host store, shared by the booths' threads (a SessionStore is used by one thread at a time).
struct HostStore {
  SessionStore store;
  std::mutex mutex;
};

struct SyncSettings {
  std::string token;
  bool rig = true;
  bool upload = true;
  double max_bytes_per_s = 0;
  const FaceModel* model = nullptr;
  const GuideSet* guide = nullptr;
  RigOptions rig_options;
  bool allow_missing = false;
};

bool valid_booth_id(const std::string& id) {
  if (id.empty() || id.size() > 64) return false;
  for (char c : id)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '_') return false;
  return true;
}

// One booth's sync round.
class BoothSync {
 public:
  BoothSync(BoothAddress address, const SyncSettings& settings, HostStore& host,
            TransferProgress& bar)
      : client_(address, settings.token), settings_(settings), host_(host), bar_(bar) {}

  json run() {
    report_ = {{"booth", client_.address().url}};
    counts_ = {};
    const auto t0 = Clock::now();
    auto done = run_sessions();
    report_["listed"] = counts_.listed;
    report_["ready"] = counts_.ready;
    report_["imported"] = counts_.imported;
    report_["downloaded_bytes"] = counts_.bytes;
    report_["resumed_bytes"] = counts_.resumed;
    report_["rigged"] = counts_.rigged;
    report_["rigs_uploaded"] = counts_.uploaded;
    report_["seconds"] = seconds_since(t0);
    report_["sessions"] = sessions_;
    if (!done) report_["error"] = done.error().message;
    sessions_ = json::array();
    return report_;
  }

 private:
  struct Counts {
    int listed = 0, ready = 0, imported = 0, rigged = 0, uploaded = 0;
    std::uint64_t bytes = 0, resumed = 0;
  };

  Result<void> run_sessions() {
    auto ready = client_.get_json("/api/offload/ready");
    if (!ready) return ready.failure();
    if (!(*ready)["booth_id"].is_string() || !valid_booth_id((*ready)["booth_id"]))
      return fail("the booth at " + client_.address().url +
                  " reports no usable booth_id: update its faceboothd (sync keys sessions by it)");
    booth_id_ = (*ready)["booth_id"].get<std::string>();
    report_["booth_id"] = booth_id_;
    if (!(*ready)["sessions"].is_array()) return fail("the booth's ready list has no sessions");
    for (const auto& s : (*ready)["sessions"]) {
      ++counts_.listed;
      if (!s["id"].is_number_integer() || !s.value("ready_for_rigging", false)) continue;
      ++counts_.ready;
      json entry = {{"booth_session", s["id"]}, {"subject", s.value("subject_name", "")}};
      auto ok = sync_session(s["id"].get<std::int64_t>(), s.value("rigs", 0),
                             s.value("rig_detail_captures", json()), entry);
      sessions_.push_back(entry);
      if (!ok) return ok;
    }
    return success();
  }

  // `booth_detail`: the detail captures of the booth's newest rig from the session (null from a
  // booth too old to say).
  Result<void> sync_session(std::int64_t booth_session, int booth_rigs, const json& booth_detail,
                            json& entry) {
    std::optional<SessionId> local;
    {
      std::lock_guard lock(host_.mutex);
      auto found = host_.store.imported_session(booth_id_, booth_session);
      if (!found) return found.failure();
      local = *found;
    }
    entry["imported"] = !local.has_value();
    if (!local) {
      auto id = fetch(booth_session, entry);
      if (!id) return id.failure();
      local = *id;
      ++counts_.imported;
    }
    entry["host_session"] = *local;
    if (!settings_.rig) return success();
    auto rig = rig_session(*local, entry);
    if (!rig) return rig.failure();
    if (!settings_.upload) {
      entry["uploaded"] = false;
      return success();
    }
    std::vector<RigDetailCapture> detail;
    {
      std::lock_guard lock(host_.mutex);
      auto found = session_detail_captures(host_.store, *local, *settings_.guide);
      if (!found) return found.failure();
      detail = std::move(*found);
    }
    // A booth with a rig from the session gets it again only when the host has built wrinkle
    // detail since (`facebooth wrinkles` runs after the first rig): its live stream then has
    // the map weights.
    if (booth_rigs > 0 && (!booth_detail.is_array() || same_detail(booth_detail, detail))) {
      entry["uploaded"] = false;
      return success();
    }
    return upload(booth_session, *rig, detail, entry);
  }

  static bool same_detail(const json& booth, const std::vector<RigDetailCapture>& host) {
    if (booth.size() != host.size()) return false;
    for (std::size_t i = 0; i < host.size(); ++i)
      if (booth[i].value("capture", -1) != host[i].capture_index ||
          booth[i].value("expression", std::string()) != host[i].expression)
        return false;
    return true;
  }

  // Downloads, checks and imports one session; a refused bundle leaves nothing behind.
  Result<SessionId> fetch(std::int64_t booth_session, json& entry) {
    const fs::path staging = host_.store.root() / ".sync" / booth_id_;
    std::error_code ec;
    fs::create_directories(staging, ec);
    if (ec) return fail("cannot create " + staging.string() + ": " + ec.message());
    const fs::path part = staging / ("session-" + std::to_string(booth_session) + ".tar.part");
    const std::string path =
        "/api/offload/sessions/" + std::to_string(booth_session) + "/bundle.tar";
    const std::string key = booth_id_ + "/" + std::to_string(booth_session);
    auto discard = [&] {
      fs::remove(part, ec);
      fs::remove(fs::path(part.string() + ".etag"), ec);
    };
    Result<SessionImport> bundle = fail("");
    for (int attempt = 0; attempt < 2; ++attempt) {
      auto got = client_.download(
          path, part,
          [&](std::uint64_t done, std::uint64_t total) { bar_.update(key, done, total); },
          settings_.max_bytes_per_s);
      bar_.finish(key);
      if (!got) return got.failure();
      counts_.bytes += got->bytes;
      counts_.resumed += got->resumed_from;
      entry["bytes"] = entry.value("bytes", std::uint64_t{0}) + got->bytes;
      entry["bundle_bytes"] = got->total;
      auto bytes = read_file_bytes(part);
      if (!bytes) return bytes.failure();
      bundle = read_session_bundle(*bytes, booth_id_, booth_session);
      discard();
      // A resumed file that does not check out may mix two versions: once more from the start.
      if (bundle || got->resumed_from == 0) break;
    }
    if (!bundle)
      return fail("session " + std::to_string(booth_session) + " of booth " + booth_id_ + " (" +
                  client_.address().url + "): " + bundle.error().message);
    std::lock_guard lock(host_.mutex);
    return host_.store.import_session(*bundle);
  }

  // Rigs the session unless a rig built from it is stored; returns the rig serving it.
  Result<RigData> rig_session(SessionId local, json& entry) {
    SessionExamples examples;
    {
      std::lock_guard lock(host_.mutex);
      auto serving = host_.store.rig_for(local);
      if (!serving) return serving.failure();
      if (*serving && (*serving)->session == local) {
        entry["rig"] = (*serving)->id;
        entry["rigged"] = false;
        return host_.store.read_rig((*serving)->id);
      }
      auto loaded = load_session_examples(host_.store, local, *settings_.model, *settings_.guide,
                                          settings_.allow_missing);
      if (!loaded)
        return fail("rigging host session " + std::to_string(local) + ": " +
                    loaded.error().message);
      examples = std::move(*loaded);
    }
    auto rigged = rig_examples(examples, *settings_.model, settings_.rig_options);
    if (!rigged) return rigged.failure();
    std::lock_guard lock(host_.mutex);
    auto id = host_.store.add_rig(examples.subject, local, rigged->data);
    if (!id) return id.failure();
    ++counts_.rigged;
    entry["rig"] = *id;
    entry["rigged"] = true;
    entry["rig_s"] = rigged->result.seconds;
    return std::move(rigged->data);
  }

  Result<void> upload(std::int64_t booth_session, const RigData& rig,
                      const std::vector<RigDetailCapture>& detail, json& entry) {
    std::string names;
    for (const auto& n : rig.shape_names) names += (names.empty() ? "" : ",") + n;
    // The captures with wrinkle detail (guide names: letters, digits and _), for the booth's
    // live map weights.
    std::string query = "?names=" + names;
    for (std::size_t i = 0; i < detail.size(); ++i)
      query += (i ? "," : "&detail=") + std::to_string(detail[i].capture_index) + ":" +
               detail[i].expression;
    const auto bs = encode_shape_bs(rig);
    auto answer =
        client_.post("/api/offload/sessions/" + std::to_string(booth_session) + "/rig" + query,
                     std::string(reinterpret_cast<const char*>(bs.data()), bs.size()),
                     "application/octet-stream");
    if (!answer) return answer.failure();
    ++counts_.uploaded;
    entry["uploaded"] = true;
    entry["booth_rig"] = (*answer).value("rig", std::int64_t{0});
    entry["detail_captures"] = static_cast<int>(detail.size());
    return success();
  }

  BoothClient client_;
  const SyncSettings& settings_;
  HostStore& host_;
  TransferProgress& bar_;
  std::string booth_id_;
  json report_;
  json sessions_ = json::array();
  Counts counts_;
};

// One round over every booth, each in its own thread (a fresh client per round: a booth that
// restarted gets a fresh connection); the combined report.
json sync_round(const std::vector<BoothAddress>& addresses, const SyncSettings& settings,
                HostStore& host, long long round) {
  std::vector<json> reports(addresses.size());
  const auto t0 = Clock::now();
  {
    TransferProgress bar("download");
    std::vector<std::unique_ptr<BoothSync>> booths;
    for (const auto& a : addresses)
      booths.push_back(std::make_unique<BoothSync>(a, settings, host, bar));
    std::vector<std::jthread> threads;
    for (std::size_t i = 0; i < booths.size(); ++i)
      threads.emplace_back([&, i] { reports[i] = booths[i]->run(); });
  }
  const double s = seconds_since(t0);
  std::uint64_t bytes = 0;
  int imported = 0, rigged = 0, uploaded = 0, failed = 0;
  for (const auto& r : reports) {
    bytes += r["downloaded_bytes"].get<std::uint64_t>();
    imported += r["imported"].get<int>();
    rigged += r["rigged"].get<int>();
    uploaded += r["rigs_uploaded"].get<int>();
    failed += r.contains("error");
  }
  return {{"round", round},
          {"booths", reports},
          {"downloaded_bytes", bytes},
          {"imported", imported},
          {"rigged", rigged},
          {"rigs_uploaded", uploaded},
          {"failed_booths", failed},
          {"seconds", s},
          {"mb_per_s", s > 0 ? static_cast<double>(bytes) / 1e6 / s : 0.0}};
}

void print_summary(const json& round) {
  for (const auto& r : round["booths"]) {
    std::cerr << "sync " << r["booth"].get<std::string>() << ": "
              << r.value("booth_id", std::string("?")) << ", " << r["ready"] << " ready, "
              << r["imported"] << " imported (" << r["downloaded_bytes"].get<std::uint64_t>() / 1000
              << " kB), " << r["rigged"] << " rigged, " << r["rigs_uploaded"] << " rigs uploaded";
    if (r.contains("error")) std::cerr << "; FAILED: " << r["error"].get<std::string>();
    std::cerr << "\n";
  }
}

Result<std::string> read_token(const std::string& file) {
  if (file.empty()) return std::string();
  auto bytes = read_file_bytes(file);
  if (!bytes) return fail("--token-file: " + bytes.error().message);
  std::string token(bytes->begin(), bytes->end());
  while (!token.empty() && std::isspace(static_cast<unsigned char>(token.back()))) token.pop_back();
  while (!token.empty() && std::isspace(static_cast<unsigned char>(token.front())))
    token.erase(token.begin());
  if (token.empty()) return fail("--token-file " + file + " is empty");
  return token;
}

int run_sync(const ParsedOptions& options) {
  std::vector<std::string> urls = options.all("booth");
  if (urls.empty()) return report_failure({"give at least one --booth URL (repeat it for more)"});
  const std::string store_dir = options.get("store");
  if (store_dir.empty()) return report_failure({"--store HOST_STORE is required"});
  std::vector<BoothAddress> addresses;
  for (const auto& url : urls) {
    auto a = parse_booth_address(url, options.flag("insecure"));
    if (!a) return report_failure(a.error());
    addresses.push_back(*a);
  }
  auto token = read_token(options.get("token-file"));
  if (!token) return report_failure(token.error());
  auto rate = options.get_double("max-rate");
  auto interval = options.get_double("interval");
  auto rounds = options.get_int("watch-rounds");
  if (!rate || !interval || !rounds)
    return report_failure(!rate ? rate.error() : !interval ? interval.error() : rounds.error());
  auto inputs = load_rig_inputs(options);
  if (!inputs) return report_failure(inputs.error());

  SyncSettings settings;
  settings.token = *token;
  settings.rig = !options.flag("no-rig");
  settings.upload = !options.flag("no-upload");
  settings.max_bytes_per_s = *rate * 1e6;
  settings.model = &inputs->model;
  settings.guide = &inputs->guide;
  settings.rig_options = inputs->rig;
  settings.allow_missing = options.flag("allow-missing");
  StoreOptions so;
  auto store = SessionStore::open(store_dir, so);
  if (!store) return report_failure(store.error());
  HostStore host{std::move(*store), {}};

  const bool watch = options.flag("watch");
  sigset_t stop;
  sigemptyset(&stop);
  sigaddset(&stop, SIGINT);
  sigaddset(&stop, SIGTERM);
  // --watch: block the stop signals before any thread starts, and wait for them between rounds
  // (a round is never cut in the middle of an import).
  if (watch) pthread_sigmask(SIG_BLOCK, &stop, nullptr);

  int failed = 0;
  for (long long round = 1;; ++round) {
    const json result = sync_round(addresses, settings, host, round);
    failed = result["failed_booths"].get<int>();
    print_summary(result);
    std::cout << (watch ? result.dump() : result.dump(2)) << std::endl;
    if (!watch || (*rounds > 0 && round >= *rounds)) break;
    timespec wait{};
    wait.tv_sec = static_cast<time_t>(*interval);
    wait.tv_nsec = static_cast<long>((*interval - static_cast<double>(wait.tv_sec)) * 1e9);
    if (sigtimedwait(&stop, nullptr, &wait) > 0) break;  // SIGINT/SIGTERM: stop between rounds
  }
  return failed == 0 ? kExitOk : kExitFailure;
}

}  // namespace

std::vector<Command> sync_commands() {
  std::vector<OptionSpec> opts = {
      {"booth", "URL", "a booth (faceboothd), http://HOST:PORT; repeat for several booths", ""},
      {"store", "DIR", "the host session store (created when missing)", ""},
      {"token-file", "FILE", "the booths' [http] token (needed from another machine)", ""},
      {"insecure", "", "allow plain HTTP to a booth on another machine", ""},
      {"watch", "", "keep syncing as sessions complete (until SIGINT/SIGTERM)", ""},
      {"interval", "S", "seconds between --watch rounds", "5"},
      {"watch-rounds", "N", "with --watch: stop after N rounds (0 = never)", "0"},
      {"max-rate", "MB/S", "limit each booth's download rate (0 = none)", "0"},
      {"no-rig", "", "import only; do not rig", ""},
      {"no-upload", "", "rig on the host but do not send the rigs back", ""},
      {"allow-missing", "", "rig sessions with missing fits from what is there", ""},
      {"guide", "FILE", "guide recipes the booths captured with (default: the project's)", ""}};
  for (auto& o : rig_option_specs()) opts.push_back(o);
  return {
      {{"sync", "fetch booths' finished sessions into a host store, rig them, send the rigs back",
        "For each booth: the sessions ready for rigging (GET /api/offload/ready) that the "
        "store has not imported are downloaded (resumed after a cut), checked (no path "
        "outside the bundle, every file's SHA-256 against the booth's manifest) and imported "
        "in one transaction, keyed by the booth's id; each is rigged as `rig --save` does and "
        "the rig uploaded to the booth, whose tracking mode then uses it. Booths sync in "
        "parallel. Running it again fetches nothing twice. JSON report on stdout (one line "
        "per round with --watch); exit status 1 when a booth failed.",
        opts},
       run_sync}};
}

}  // namespace fb::cli
