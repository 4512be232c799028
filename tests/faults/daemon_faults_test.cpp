// Issue 41, item 4: faults a deployed booth meets, injected into the real daemon. A camera that
// stalls or fails mid-take (the synthetic camera's stall_after / fail_after), and a full disk
// (enospc_preload.c under the real faceboothd binary) during a capture commit and during the
// end-of-session export. Each must leave the store verifiable with no partial files, say what
// happened, and let the session go on once the fault is gone. A wall clock set back and forward
// mid-session (clock_jump_preload.c) must not disturb the session, and the log says it happened.
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "firmware/daemon/daemon.hpp"
#include "firmware/daemon/daemon_config.hpp"
#include "firmware/daemon/session_machine.hpp"
#include "firmware/daemon/session_records.hpp"
#include "storage/durable_file.hpp"
#include "storage/session_store.hpp"
#include "tests/common/daemon_fixture.hpp"

namespace fb {
namespace {

namespace fs = std::filesystem;
using std::chrono::milliseconds;

class DaemonFaults : public test::DaemonFixture {
 protected:
  DaemonFaults()
      : DaemonFixture("fb-faults-", R"({"expressions": [
      {"id": 0, "name": "neutral", "label": "Neutral", "weights": {}},
      {"id": 1, "name": "smile", "label": "Smile", "weights": {"mouthSmile_L": 0.8, "mouthSmile_R": 0.8}}]})") {
  }

  // Runs the real faceboothd headless with `env` before it; returns its exit code, stderr in
  // `log`.
  int run_headless(const std::string& env, std::string& log) {
    std::ofstream(dir_ / "faceboothd.toml") << to_toml(config());
    const fs::path err = dir_ / "stderr.txt";
    const std::string command = env + " " + FB_FACEBOOTHD + " --config " +
                                (dir_ / "faceboothd.toml").string() +
                                " --run-session-headless --subject Disk >" +
                                (dir_ / "stdout.txt").string() + " 2>" + err.string();
    const int rc = std::system(command.c_str());
    std::stringstream text;
    text << std::ifstream(err).rdbuf();
    log = text.str();
    return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
  }
};

TEST_F(DaemonFaults, CameraThatStallsOrFailsMidTakeIsReportedAndTheSessionResumes) {
  struct Case {
    const char* fault;
    const char* says;
  };
  for (const Case& k : {Case{"stall_after=3", "stopped delivering frames after 3 frames"},
                        Case{"fail_after=3", "the camera failed after 3 frames"}}) {
    fs::remove_all(dir_ / "data");
    std::int64_t session = 0;
    {
      auto d = make(config(std::string("synthetic:seed=4,") + k.fault));
      ASSERT_TRUE(d);
      ASSERT_TRUE(d->start());
      d->post(KioskInput::kStart, "Stall");
      wait_for(*d, [](auto& s) { return s["state"] == "guide"; });
      ASSERT_TRUE(d->press({ButtonId::kMain, PressKind::kShort}));
      auto s = wait_for(*d, [](auto& s) { return s["state"] == "error"; });
      session = s["session"];
      const std::string error = s["error"];
      EXPECT_NE(error.find(k.says), std::string::npos) << error;
      EXPECT_NE(error.find("check its cable and power"), std::string::npos) << error;
      EXPECT_EQ(s["led"], "error");
      EXPECT_NE(s["message"].get<std::string>().find("Press the button"), std::string::npos);
    }
    expect_store_consistent();
    // The camera is back: the next daemon resumes the session at the capture that failed.
    auto d = make(config());
    ASSERT_TRUE(d);
    ASSERT_TRUE(d->start());
    auto s = wait_for(*d, [](auto& s) { return s["state"] == "guide"; });
    EXPECT_TRUE(s["resumed"].get<bool>());
    EXPECT_EQ(s["session"], session);
    EXPECT_EQ(s["capture_index"], 0);
    auto r = d->run_headless_session("unused");
    ASSERT_TRUE(r) << r.error().message;
    EXPECT_EQ(r->session_id, session);
    EXPECT_EQ(r->captures_done, 2);
  }
}

TEST_F(DaemonFaults, FullDiskDuringCaptureCommitLosesNothingAndResumes) {
  std::string log;
  // Every data file of the store's sessions fails to write, 4 KB into it.
  const std::string env = "LD_PRELOAD=" + std::string(FB_ENOSPC_PRELOAD) +
                          " FB_FAULT_ENOSPC_MATCH=/store/sessions/ FB_FAULT_ENOSPC_AFTER=4096";
  EXPECT_EQ(run_headless(env, log), 1) << log;
  EXPECT_NE(log.find("no space left"), std::string::npos) << log;
  EXPECT_NE(log.find("free space"), std::string::npos) << log;
  expect_store_consistent();
  ASSERT_NO_FATAL_FAILURE(expect_one_session(false, 0));
  // Space again: the same session is resumed and completed.
  EXPECT_EQ(run_headless("", log), 0) << log;
  expect_store_consistent();
  ASSERT_NO_FATAL_FAILURE(expect_one_session(true, 2));
}

TEST_F(DaemonFaults, FullDiskDuringExportPublishesNothingAndKeepsTheSession) {
  std::string log;
  const std::string env = "LD_PRELOAD=" + std::string(FB_ENOSPC_PRELOAD) +
                          " FB_FAULT_ENOSPC_MATCH=/exports/ FB_FAULT_ENOSPC_AFTER=1000";
  EXPECT_EQ(run_headless(env, log), 1) << log;
  EXPECT_NE(
      log.find("No space left on device (free space and export again; nothing was published)"),
      std::string::npos)
      << log;
  expect_store_consistent();
  // Nothing half-written is published: the exports folder holds no session folder.
  int published = 0;
  if (fs::exists(dir_ / "data" / "exports"))
    for (const auto& e : fs::directory_iterator(dir_ / "data" / "exports")) {
      ADD_FAILURE() << "left in exports: " << e.path();
      ++published;
    }
  EXPECT_EQ(published, 0);
  // The session itself is complete and stored; with space again it exports.
  std::int64_t session = 0;
  ASSERT_NO_FATAL_FAILURE(expect_one_session(true, std::nullopt, &session));
  auto records = open_session_records(dir_ / "data");
  ASSERT_TRUE(records) << records.error().message;
  auto out = (*records)->export_session(session, dir_ / "data" / "exports");
  ASSERT_TRUE(out) << out.error().message;
  EXPECT_TRUE(fs::exists(*out / "manifest.json") || !fs::is_empty(*out));
}

TEST_F(DaemonFaults, WallClockSetMidSessionIsReportedAndChangesNothing) {
  std::string log;
  // An hour back soon after start-up (during the landmark model's load or the session), then,
  // in a second run, a day forward: NTP stepping the clock of a booth without a battery-backed
  // clock, an operator fixing it.
  const std::string clock = "LD_PRELOAD=" + std::string(FB_CLOCK_PRELOAD) +
                            " FB_FAULT_CLOCK_JUMP_AFTER_S=0.3 FB_FAULT_CLOCK_JUMP_S=";
  ASSERT_EQ(run_headless(clock + "-3600", log), 0) << log;
  EXPECT_NE(log.find("the wall clock was set back by 3600 s"), std::string::npos) << log;
  expect_store_consistent();
  ASSERT_EQ(run_headless(clock + "86400", log), 0) << log;
  EXPECT_NE(log.find("the wall clock was set forward by 86400 s"), std::string::npos) << log;
  expect_store_consistent();
  auto store = open_store();
  ASSERT_TRUE(store);
  auto sessions = store->sessions();
  ASSERT_TRUE(sessions);
  ASSERT_EQ(sessions->size(), 2u);
  for (const auto& s : *sessions) {
    EXPECT_TRUE(s.complete) << "session " << s.id;
    EXPECT_EQ(s.done_count, 2) << "session " << s.id;
    EXPECT_TRUE(fs::exists(dir_ / "data" / "exports" / ("session-" + std::to_string(s.id))))
        << "session " << s.id << " was not exported";
  }
}

}  // namespace
}  // namespace fb
