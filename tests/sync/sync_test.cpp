// facebooth sync against real booths: faceboothd processes (synthetic camera, short headless
// sessions) on loopback with a token, one host store (a real SQLite file), the real facebooth
// binary; and a fake booth (cpp-httplib in the test) serving bundles that must be refused.
#include <gtest/gtest.h>
#include <ifaddrs.h>

#include <nlohmann/json.hpp>

#include "storage/bundle_import.hpp"
#include "storage/session_store.hpp"
#include "storage/sha256.hpp"
#include "tests/common/bundle_writer.hpp"
#include "tests/fuzz/regression_input.hpp"
#include "tests/sync/booth_process.hpp"

namespace fb {
namespace {

using nlohmann::json;
using test::Booth;
using test::ChildProcess;
namespace fs = std::filesystem;

constexpr const char* kToken = "studio-token-0123456789";

struct SyncRun {
  int exit_code = -1;
  json report;      // stdout
  std::string err;  // stderr
};

class SyncTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("fb-sync-test-" + std::to_string(::getpid()) + "-" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    std::ofstream(token_file()) << kToken << "\n";
  }
  void TearDown() override {
    if (!HasFailure()) fs::remove_all(dir_);
  }
  fs::path token_file() const { return dir_ / "token"; }
  fs::path host() const { return dir_ / "host-store"; }

  SyncRun sync(const std::string& args) {
    const fs::path err = dir_ / "sync.err";
    auto run = test::run_command(std::string(FB_CLI_PATH) + " sync --store " + host().string() +
                                     " " + args + " 2>" + err.string(),
                                 test::Stderr::kToLog);
    SyncRun out;
    out.exit_code = run.exit_code;
    out.report = json::parse(run.out, nullptr, false);
    std::ifstream in(err);
    out.err.assign(std::istreambuf_iterator<char>(in), {});
    std::cerr << out.err;
    return out;
  }

  SessionStore open_host() {
    StoreOptions ro;
    ro.read_only = true;
    auto store = SessionStore::open(host(), ro);
    EXPECT_TRUE(store) << store.error().message;
    return std::move(*store);
  }

  fs::path dir_;
};

std::string booth_id_of(const Booth& booth) {
  std::ifstream in(booth.dir() / "data" / "booth-id");
  std::string id;
  std::getline(in, id);
  return id;
}

// Tracking mode on the booth until its status names the tracked identity; returns it.
std::string tracked_identity(const Booth& booth, const std::string& want_prefix) {
  httplib::Client http("127.0.0.1", booth.port());
  auto mode = http.Post("/api/mode", R"({"mode": "tracking"})", "application/json");
  if (!mode || mode->status != 202) return "mode switch refused";
  std::string identity;
  for (int i = 0; i < 300; ++i) {
    if (auto r = http.Get("/api/status"); r && r->status == 200) {
      auto s = json::parse(r->body, nullptr, false);
      if (!s.is_discarded() && s["state"] == "tracking") {
        identity = s["tracking"]["identity"].get<std::string>();
        if (identity.rfind(want_prefix, 0) == 0) return identity;
      }
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  return identity;
}

double max_abs_diff(const std::vector<float>& a, const std::vector<float>& b) {
  if (a.size() != b.size()) return 1e30;
  double d = 0;
  for (std::size_t i = 0; i < a.size(); ++i) d = std::max(d, double(std::abs(a[i] - b[i])));
  return d;
}

// Issue 38's first "done when": two booths, one host store; both imported, rigged, rigs back on
// the booths (their tracking mode uses them); a second sync transfers nothing.
TEST_F(SyncTest, TwoBoothsImportRigAndTrackWithTheUploadedRigs) {
  Booth a(dir_ / "booth-a", "synthetic:seed=4", kToken);
  Booth b(dir_ / "booth-b", "synthetic:seed=11", kToken);
  const json sa = a.capture("Ada"), sb = b.capture("Bo");
  ASSERT_TRUE(sa.is_object() && sb.is_object()) << "a headless session failed (see the log)";
  ASSERT_TRUE(a.start());
  ASSERT_TRUE(b.start());

  const std::string booths = "--booth " + a.url() + " --booth " + b.url();
  auto first = sync(booths + " --token-file " + token_file().string());
  ASSERT_EQ(first.exit_code, 0) << first.err;
  ASSERT_TRUE(first.report.is_object());
  const json& r = first.report;
  EXPECT_EQ(r["imported"], 2) << r.dump(1);
  EXPECT_EQ(r["rigged"], 2);
  EXPECT_EQ(r["rigs_uploaded"], 2);
  EXPECT_EQ(r["failed_booths"], 0);
  EXPECT_GT(r["downloaded_bytes"].get<std::uint64_t>(), 1'000'000u);  // three captures each
  std::printf("first sync: %.2f MB in %.2f s (%.1f MB/s) including rigging\n",
              r["downloaded_bytes"].get<double>() / 1e6, r["seconds"].get<double>(),
              r["mb_per_s"].get<double>());
  ASSERT_EQ(r["booths"].size(), 2u);
  const json& ra = r["booths"][0];
  const json& rb = r["booths"][1];
  EXPECT_EQ(ra["booth_id"], booth_id_of(a));
  EXPECT_EQ(rb["booth_id"], booth_id_of(b));
  EXPECT_NE(ra["booth_id"], rb["booth_id"]);

  // The host store: both sessions, keyed by their booth (both are session 1 of subject 1 on
  // their booth), with their captures, fits, landmarks and fused depth, and a rig each.
  {
    SessionStore host = open_host();
    auto verify = host.verify();
    ASSERT_TRUE(verify && verify->ok()) << (verify ? verify->problems.size() : 0);
    auto sessions = host.sessions();
    ASSERT_TRUE(sessions);
    ASSERT_EQ(sessions->size(), 2u);
    ASSERT_EQ(host.subjects()->size(), 2u);
    StoreOptions ro;
    ro.read_only = true;
    for (std::size_t i = 0; i < 2; ++i) {
      const Booth& booth = i == 0 ? a : b;
      const json& booth_session = i == 0 ? sa : sb;
      // The booths import in parallel: find this booth's session by its origin.
      auto it = std::find_if(sessions->begin(), sessions->end(), [&](const SessionInfo& s) {
        return s.origin_booth == booth_id_of(booth);
      });
      ASSERT_NE(it, sessions->end());
      const SessionInfo& s = *it;
      EXPECT_EQ(host.subject(s.subject)->name, i == 0 ? "Ada" : "Bo");
      EXPECT_EQ(s.origin_session, booth_session["session"].get<std::int64_t>());
      EXPECT_TRUE(s.complete);
      EXPECT_EQ(s.done_count, 3);
      EXPECT_FALSE(s.calibration_json.empty());
      auto capture = host.read_capture(s.id, 1);
      ASSERT_TRUE(capture) << capture.error().message;
      EXPECT_EQ(capture->landmarks.size(), 68u);
      EXPECT_EQ(capture->fused_depth.width, 640);
      EXPECT_EQ(capture->frames.size(), 1u);  // the frontal colour frame
      EXPECT_EQ(capture->frames[0].color.width, 640);
      EXPECT_GT(capture->info.qa_scores.count("fit_rms_mm"), 0u);
      // The fitted meshes are the booth's, to the float.
      auto booth_store = SessionStore::open(booth.store(), ro);
      ASSERT_TRUE(booth_store);
      auto booth_meshes = booth_store->meshes(s.origin_session);
      auto host_meshes = host.meshes(s.id);
      ASSERT_TRUE(booth_meshes && host_meshes);
      ASSERT_EQ(host_meshes->size(), 3u);
      EXPECT_EQ((*host_meshes)[0].role, MeshRole::kNeutral);
      auto booth_mesh = booth_store->read_mesh(booth_meshes->back().id);
      auto host_mesh = host.read_mesh(host_meshes->back().id);
      ASSERT_TRUE(booth_mesh && host_mesh);
      EXPECT_LT(max_abs_diff(booth_mesh->positions, host_mesh->positions), 1e-6);
      auto rig = host.rig_for(s.id);
      ASSERT_TRUE(rig && *rig);
      EXPECT_EQ((*rig)->session, s.id);
      EXPECT_EQ((*rig)->shape_names.size(), 53u);
    }
  }

  // Each booth tracks its subject with the rig the host sent back.
  for (std::size_t i = 0; i < 2; ++i) {
    const Booth& booth = i == 0 ? a : b;
    const json& entry = r["booths"][i]["sessions"][0];
    ASSERT_TRUE(entry["uploaded"].get<bool>()) << entry.dump();
    StoreOptions ro;
    ro.read_only = true;
    auto booth_store = SessionStore::open(booth.store(), ro);
    ASSERT_TRUE(booth_store);
    auto session = booth_store->session(entry["booth_session"].get<std::int64_t>());
    ASSERT_TRUE(session);
    const std::string want = "stored rig " + std::to_string(entry["booth_rig"].get<int>()) +
                             " of subject " + std::to_string(session->subject);
    EXPECT_EQ(tracked_identity(booth, want).rfind(want, 0), 0u) << want;
  }

  // Nothing twice.
  auto second = sync(booths + " --token-file " + token_file().string());
  ASSERT_EQ(second.exit_code, 0) << second.err;
  EXPECT_EQ(second.report["downloaded_bytes"], 0);
  EXPECT_EQ(second.report["imported"], 0);
  EXPECT_EQ(second.report["rigged"], 0);
  EXPECT_EQ(second.report["rigs_uploaded"], 0);
  EXPECT_EQ(open_host().sessions()->size(), 2u);
}

// Issue 40 item 5 end to end: sync sends the rig; `facebooth wrinkles` then builds the session's
// detail on the host; the next sync sends the rig again with its detail captures (the booth's
// ready list said its rig has none), and the booth's live tracking JSON carries one map weight
// per capture; a third sync sends nothing.
TEST_F(SyncTest, WrinkleDetailBuiltAfterTheRigReachesTheBoothsLiveStream) {
  Booth a(dir_ / "booth-a", "synthetic:seed=4", kToken);
  const json sa = a.capture("Wren");
  ASSERT_TRUE(sa.is_object()) << "a headless session failed (see the log)";
  ASSERT_TRUE(a.start());
  const std::string args = "--booth " + a.url() + " --token-file " + token_file().string();
  auto first = sync(args);
  ASSERT_EQ(first.exit_code, 0) << first.err;
  EXPECT_EQ(first.report["rigs_uploaded"], 1) << first.report.dump(1);
  const json entry = first.report["booths"][0]["sessions"][0];
  EXPECT_EQ(entry["detail_captures"], 0) << entry.dump();
  const auto host_session = entry["host_session"].get<std::int64_t>();

  auto wrinkles =
      test::run_command(std::string(FB_CLI_PATH) + " wrinkles --size 256 --store " +
                            host().string() + " --session " + std::to_string(host_session),
                        test::Stderr::kToLog);
  ASSERT_EQ(wrinkles.exit_code, 0) << wrinkles.out;
  std::vector<RigDetailCapture> want;
  {
    SessionStore host_store = open_host();
    auto captures = host_store.captures(host_session);
    ASSERT_TRUE(captures);
    for (const auto& c : *captures)
      if (c.index > 0) want.push_back({c.index, c.expression});
  }
  ASSERT_EQ(want.size(), 2u);

  auto second = sync(args);
  ASSERT_EQ(second.exit_code, 0) << second.err;
  EXPECT_EQ(second.report["rigged"], 0);
  ASSERT_EQ(second.report["rigs_uploaded"], 1) << second.report.dump(1);
  EXPECT_EQ(second.report["booths"][0]["sessions"][0]["detail_captures"], 2);
  {
    StoreOptions ro;
    ro.read_only = true;
    auto booth_store = SessionStore::open(a.store(), ro);
    ASSERT_TRUE(booth_store);
    auto rig = booth_store->rig_for(sa["session"].get<std::int64_t>());
    ASSERT_TRUE(rig && *rig);
    EXPECT_EQ((*rig)->detail_captures, want);
  }
  const std::string keys = want[0].expression + "@1, " + want[1].expression + "@2";
  EXPECT_NE(tracked_identity(a, "stored rig").find("wrinkle map weights of 2 captures (" + keys),
            std::string::npos);
  httplib::Client http("127.0.0.1", a.port());
  json live;
  for (int i = 0; i < 100 && !live.is_object(); ++i) {
    if (auto r = http.Get("/api/tracking/live"); r && r->status == 200)
      live = json::parse(r->body, nullptr, false);
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  ASSERT_TRUE(live.is_object());
  ASSERT_TRUE(live.contains("detail_weights")) << live.dump();
  EXPECT_EQ(live["detail_weights"].size(), 2u);
  EXPECT_TRUE(live["detail_weights"].contains(want[1].expression + "@2")) << live.dump();

  auto third = sync(args);
  ASSERT_EQ(third.exit_code, 0) << third.err;
  EXPECT_EQ(third.report["rigs_uploaded"], 0) << third.report.dump(1);
}

// A non-loopback address of this machine (empty when it has none).
std::string outside_address() {
  ifaddrs* list = nullptr;
  if (::getifaddrs(&list) != 0) return {};
  std::string found;
  for (ifaddrs* i = list; i && found.empty(); i = i->ifa_next) {
    if (!i->ifa_addr || i->ifa_addr->sa_family != AF_INET) continue;
    char text[INET_ADDRSTRLEN];
    ::inet_ntop(AF_INET, &reinterpret_cast<sockaddr_in*>(i->ifa_addr)->sin_addr, text, sizeof text);
    if (std::string(text).rfind("127.", 0) != 0) found = text;
  }
  ::freeifaddrs(list);
  return found;
}

// Issue 38 item 5: from another address the offload API needs the token, and sync refuses plain
// HTTP to a booth that is not local unless told --insecure. The same booth reached by another
// address is still the same booth (its id): nothing is fetched twice.
TEST_F(SyncTest, OffloadFromAnotherAddressNeedsTheTokenAndInsecure) {
  const std::string ip = outside_address();
  if (ip.empty()) GTEST_SKIP() << "this machine has no non-loopback IPv4 address";
  Booth a(dir_ / "booth-a", "synthetic:seed=4", kToken, "0.0.0.0");
  ASSERT_TRUE(a.capture("Ada").is_object());
  ASSERT_TRUE(a.start());
  const std::string remote = "http://" + ip + ":" + std::to_string(a.port());

  httplib::Client http(ip, a.port());
  auto anonymous = http.Get("/api/offload/ready");
  ASSERT_TRUE(anonymous);
  EXPECT_EQ(anonymous->status, 401);
  EXPECT_EQ(http.Get("/api/offload/sessions/1/bundle.tar")->status, 401);
  httplib::Headers bearer = {{"Authorization", std::string("Bearer ") + kToken}};
  EXPECT_EQ(http.Get("/api/offload/ready", bearer)->status, 200);

  auto plain = sync("--booth " + remote + " --token-file " + token_file().string());
  EXPECT_EQ(plain.exit_code, 1);
  EXPECT_NE(plain.err.find("--insecure"), std::string::npos) << plain.err;
  EXPECT_FALSE(fs::exists(host() / "facebooth.db"));  // refused before anything was opened

  auto no_token = sync("--insecure --booth " + remote);
  EXPECT_EQ(no_token.exit_code, 1);
  EXPECT_NE(no_token.err.find("--token-file"), std::string::npos) << no_token.err;

  auto ok =
      sync("--insecure --no-rig --booth " + remote + " --token-file " + token_file().string());
  ASSERT_EQ(ok.exit_code, 0) << ok.err;
  EXPECT_EQ(ok.report["imported"], 1);
  auto local = sync("--no-rig --booth " + a.url());
  ASSERT_EQ(local.exit_code, 0) << local.err;
  EXPECT_EQ(local.report["imported"], 0);
  EXPECT_EQ(local.report["downloaded_bytes"], 0);
}

// Issue 38: a booth that goes away in the middle of a transfer leaves the host store as it was
// (it passes `store info --verify`), and the next sync resumes and completes.
TEST_F(SyncTest, BoothKilledMidTransferLeavesTheStoreAndTheNextSyncResumes) {
  // Six captures (~8 MB): the booth's kernel still sends what it had queued after the kill (up
  // to its 4 MiB socket buffer), so the bundle must be larger for the transfer to be cut.
  Booth a(dir_ / "booth-a", "synthetic:seed=4", kToken, "127.0.0.1", 6);
  ASSERT_TRUE(a.capture("Ada").is_object());
  ASSERT_TRUE(a.start());
  const fs::path part = host() / ".sync" / booth_id_of(a) / "session-1.tar.part";

  // 1 MB/s so the few-MB bundle takes seconds: the kill lands in the middle.
  ChildProcess syncing;
  ASSERT_TRUE(syncing.start({FB_CLI_PATH, "sync", "--store", host().string(), "--booth", a.url(),
                             "--max-rate", "1", "--no-rig"},
                            dir_ / "sync-killed.log"));
  std::uint64_t seen = 0;
  for (int i = 0; i < 600 && seen < 300'000; ++i) {
    std::error_code ec;
    seen = fs::exists(part, ec) ? fs::file_size(part, ec) : 0;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ASSERT_GE(seen, 300'000u) << "the transfer never started";
  a.kill();
  const int code = [&] {
    for (int i = 0; i < 300; ++i) {
      if (auto c = syncing.poll()) return *c;
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    return -2;
  }();
  EXPECT_EQ(code, 1);
  std::ifstream log(dir_ / "sync-killed.log");
  const std::string text((std::istreambuf_iterator<char>(log)), {});
  EXPECT_NE(text.find("went away"), std::string::npos) << text;
  const std::uint64_t kept = fs::file_size(part);
  std::printf("killed the booth with %llu bytes transferred\n", (unsigned long long)kept);

  auto info = test::run_command(
      std::string(FB_CLI_PATH) + " store info --verify --store " + host().string(),
      test::Stderr::kMerged);
  EXPECT_EQ(info.exit_code, 0) << info.out;
  EXPECT_EQ(open_host().sessions()->size(), 0u);
  EXPECT_EQ(open_host().subjects()->size(), 0u);

  ASSERT_TRUE(a.start());  // the booth is back
  auto again = sync("--booth " + a.url());
  ASSERT_EQ(again.exit_code, 0) << again.err;
  const json& entry = again.report["booths"][0]["sessions"][0];
  EXPECT_EQ(again.report["imported"], 1);
  EXPECT_EQ(again.report["rigged"], 1);
  EXPECT_EQ(again.report["booths"][0]["resumed_bytes"], kept) << again.report.dump(1);
  EXPECT_EQ(entry["bytes"].get<std::uint64_t>() + kept, entry["bundle_bytes"].get<std::uint64_t>());
  EXPECT_GT(entry["bytes"].get<std::uint64_t>(), 1'000'000u);  // a real part came after the cut
  EXPECT_FALSE(fs::exists(part));
  SessionStore store = open_host();
  auto verify = store.verify();
  ASSERT_TRUE(verify && verify->ok());
  ASSERT_EQ(store.sessions()->size(), 1u);
  EXPECT_EQ((*store.sessions())[0].done_count, 6);
}

// --watch: a session completed on the booth while sync watches is imported, rigged and its
// rig sent back in a later round; SIGTERM stops the watch between rounds, cleanly.
TEST_F(SyncTest, WatchPicksUpASessionCompletedWhileItRuns) {
  Booth a(dir_ / "booth-a", "synthetic:seed=6", kToken);
  ASSERT_TRUE(a.start());
  ChildProcess watching;
  const fs::path log = dir_ / "sync-watch.log";
  ASSERT_TRUE(watching.start({FB_CLI_PATH, "sync", "--watch", "--interval", "0.5", "--store",
                              host().string(), "--booth", a.url()},
                             log));
  // A session through the booth's API, as the kiosk page drives it.
  httplib::Client http("127.0.0.1", a.port());
  ASSERT_EQ(http.Post("/api/session/start", R"({"subject": "Cy"})", "application/json")->status,
            202);
  std::string pressed;  // the state + capture a press was sent for (one press each)
  bool complete = false;
  for (int i = 0; i < 1200 && !complete; ++i) {
    auto r = http.Get("/api/status");
    if (!r || r->status != 200) continue;
    const json s = json::parse(r->body);
    const std::string now = s["state"].get<std::string>();
    const std::string at = now + s["capture_index"].dump() + "/" + s["attempts"].dump();
    if ((now == "guide" || now == "retry") && at != pressed) {
      http.Post("/api/session/next", "{}", "application/json");
      pressed = at;
    }
    complete = now == "complete" || (now == "idle" && !pressed.empty());
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  ASSERT_TRUE(complete);
  // The watch's rounds (one JSON line each) until one has imported and uploaded it.
  json done;
  for (int i = 0; i < 1200 && done.is_null(); ++i) {
    std::ifstream in(log);
    for (std::string line; std::getline(in, line);) {
      if (line.empty() || line.front() != '{') continue;
      const json round = json::parse(line, nullptr, false);
      if (!round.is_discarded() && round["rigs_uploaded"] == 1) done = round;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  ASSERT_FALSE(done.is_null()) << "no round imported the session";
  EXPECT_EQ(done["imported"], 1);
  EXPECT_GT(done["round"].get<int>(), 1);  // it watched before the session was there
  const int status = watching.kill(SIGTERM);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << status;
  SessionStore store = open_host();
  ASSERT_EQ(store.sessions()->size(), 1u);
  EXPECT_EQ(store.subject(store.sessions()->front().subject)->name, "Cy");
}

// ------------------------------------------------------------------ refused bundles

using test::bundle;
using test::BundleFile;
using test::tar_entry;
const std::string kSessionJson = test::session_json();

// A booth that serves one session whose bundle is `tar`.
class FakeBooth {
 public:
  explicit FakeBooth(std::string tar) : tar_(std::move(tar)) {
    server_.Get("/api/offload/ready", [](const httplib::Request&, httplib::Response& res) {
      res.set_content(json({{"booth_id", "fake-booth"},
                            {"sessions",
                             {{{"id", 1},
                               {"subject", 1},
                               {"subject_name", "x"},
                               {"ready_for_rigging", true},
                               {"rigs", 0}}}}})
                          .dump(),
                      "application/json");
    });
    server_.Get("/api/offload/sessions/1/bundle.tar",
                [this](const httplib::Request&, httplib::Response& res) {
                  res.set_content(tar_, "application/x-tar");
                });
    port_ = server_.bind_to_any_port("127.0.0.1");
    thread_ = std::thread([this] { server_.listen_after_bind(); });
    while (!server_.is_running()) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  ~FakeBooth() {
    server_.stop();
    thread_.join();
  }
  std::string url() const { return "http://127.0.0.1:" + std::to_string(port_); }

 private:
  std::string tar_;
  httplib::Server server_;
  int port_ = 0;
  std::thread thread_;
};

// Nothing of a refused bundle anywhere: no session, no staging file, no escaped file.
void expect_nothing_written(const fs::path& dir, SessionStore store) {
  EXPECT_EQ(store.sessions()->size(), 0u);
  EXPECT_EQ(store.subjects()->size(), 0u);
  for (auto& e : fs::recursive_directory_iterator(dir)) {
    EXPECT_EQ(e.path().filename().string().find("escaped"), std::string::npos) << e.path();
    EXPECT_NE(e.path().extension(), ".part") << "staging file left: " << e.path();
  }
}

TEST_F(SyncTest, RefusesAPathTraversalEntryWritingNothing) {
  const std::string evil = "owned";
  FakeBooth booth(bundle({{"session-1/session.json", kSessionJson, "session.json", kSessionJson},
                          {"session-1/../../escaped.txt", evil, "escaped.txt", evil}}));
  auto run = sync("--booth " + booth.url());
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find("'session-1/../../escaped.txt' is a path with a '..' component"),
            std::string::npos)
      << run.err;
  EXPECT_NE(run.err.find("nothing was written"), std::string::npos);
  expect_nothing_written(dir_, open_host());
}

TEST_F(SyncTest, RefusesAWrongSha256WritingNothing) {
  const std::string mesh = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  FakeBooth booth(bundle({{"session-1/session.json", kSessionJson, "session.json", kSessionJson},
                          {"session-1/capture-00-neutral/mesh.obj", mesh + "# altered\n",
                           "capture-00-neutral/mesh.obj", mesh}}));
  auto run = sync("--booth " + booth.url());
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find("'capture-00-neutral/mesh.obj' does not match the SHA-256"),
            std::string::npos)
      << run.err;
  expect_nothing_written(dir_, open_host());
}

// The pure listing refuses, by name, what extraction could abuse.
TEST(BundleImport, ListTarRefusesWhatCouldLandOutsideTheFolder) {
  auto list = [](const std::string& tar) {
    return list_tar(std::span(reinterpret_cast<const std::uint8_t*>(tar.data()), tar.size()));
  };
  const std::string end(1024, '\0');
  auto ok = list(tar_entry("session-1/a.txt", "abc") + end);
  ASSERT_TRUE(ok) << ok.error().message;
  ASSERT_EQ(ok->size(), 1u);
  EXPECT_EQ((*ok)[0].size, 3u);
  struct Case {
    std::string tar, why;
  } cases[] = {
      {tar_entry("/etc/passwd", "x") + end, "an absolute path"},
      {tar_entry("session-1/../x", "x") + end, "a '..' component"},
      {tar_entry("session-1//x", "x") + end, "an empty component"},
      {tar_entry("session-1/link", "", '2') + end, "a symbolic link"},
      {tar_entry("session-1/hard", "", '1') + end, "a hard link"},
      {tar_entry("session-1/a", "x") + tar_entry("session-1/a", "y") + end, "listed twice"},
      {tar_entry("session-1/a", "abc").substr(0, 600), "truncated"},
      {tar_entry("session-1/a", "x").replace(0, 1, "t") + end, "wrong checksum"},
  };
  for (const auto& c : cases) {
    auto r = list(c.tar);
    ASSERT_FALSE(r) << c.why;
    EXPECT_NE(r.error().message.find(c.why), std::string::npos) << r.error().message;
  }
  // A file the manifest does not list is refused too (nothing unchecked gets in).
  const std::string tar =
      bundle({{"session-1/session.json", kSessionJson, "session.json", kSessionJson},
              {"session-1/extra.bin", "x", "", ""}});
  auto read = read_session_bundle(
      std::span(reinterpret_cast<const std::uint8_t*>(tar.data()), tar.size()), "fake-booth", 1);
  ASSERT_FALSE(read);
  EXPECT_NE(read.error().message.find("not listed in the bundle's manifest"), std::string::npos)
      << read.error().message;
}

// A session.json a hostile or broken booth could send: members missing or of the wrong type are
// refused with the reason, never read out of bounds or thrown past the caller (bundle_fuzz found
// the first: tests/fuzz/regressions/bundle_fuzz/).
TEST(BundleImport, MalformedSessionJsonIsRefusedNotMisread) {
  const std::string found_by_fuzzing =
      test::fuzz_regression("bundle_fuzz", "session_json_without_session_id", true);
  const std::string cases[] = {
      found_by_fuzzing,
      R"({"format": 7, "session": 1, "subject_id": 1, "captures": []})",
      R"({"format": "facebooth-session-bundle", "session": 1, "subject_id": 1, "captures": [],
          "subject": 5})",
      R"({"format": "facebooth-session-bundle", "session": 1, "subject_id": 1,
          "captures": [{"index": 0, "expression": "n", "state": "pending", "attempts": "x"}]})",
      R"({"format": "facebooth-session-bundle", "session": 1, "subject_id": 1,
          "captures": [{"index": 0, "expression": "n", "state": "done"}]})",
      R"({"format": "facebooth-session-bundle", "session": 1, "subject_id": 1, "captures": [7]})",
  };
  int refused = 0;
  for (const auto& session : cases) {
    const std::string tar = bundle({{"session-1/session.json", session, "session.json", session}});
    auto read = read_session_bundle(
        std::span(reinterpret_cast<const std::uint8_t*>(tar.data()), tar.size()), "b", 0);
    if (!read) {
      ++refused;
      EXPECT_NE(read.error().message.find("session"), std::string::npos) << read.error().message;
    }
  }
  // The fuzzer's input lacks "session", the 2nd has a numeric format, the 5th a done capture
  // without its colour frame, the 6th a capture that is no object: refused. A numeric subject
  // name and attempts are read as absent: accepted.
  EXPECT_EQ(refused, 4);
}

}  // namespace
}  // namespace fb
