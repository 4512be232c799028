// The in-process daemon tests' common ground: a temporary data directory named after the test
// with a short guide (a whole session takes about a second), a quick daemon configuration, the
// daemon made without signal handling, and a wait on its status (bounded only against hangs:
// never a timing check), the store's consistency after a fault. Used by tests/daemon and
// tests/faults.
#pragma once

#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "firmware/daemon/daemon.hpp"
#include "firmware/daemon/daemon_config.hpp"
#include "storage/durable_file.hpp"
#include "storage/session_store.hpp"

namespace fb::test {

// Neutral, smile and jaw open.
inline constexpr const char* kThreeStepGuide = R"({"expressions": [
  {"id": 0, "name": "neutral", "label": "Neutral", "weights": {}},
  {"id": 1, "name": "smile", "label": "Smile", "weights": {"mouthSmile_L": 0.8, "mouthSmile_R": 0.8}},
  {"id": 2, "name": "jaw_open", "label": "Jaw open", "weights": {"jawOpen": 0.6}}]})";

class DaemonFixture : public ::testing::Test {
 protected:
  DaemonFixture(std::string prefix, std::string guide_json)
      : prefix_(std::move(prefix)), guide_json_(std::move(guide_json)) {}

  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           (prefix_ + std::to_string(::getpid()) + "-" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    std::ofstream(dir_ / "guide.json") << guide_json_;
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  // 8-frame takes on demand (not real time), no preview, any free port.
  DaemonConfig config(const std::string& uri = "synthetic:seed=4", double preview_fps = 0) const {
    DaemonConfig c = default_daemon_config();
    c.camera.uri = uri;
    c.camera.capture_frames = 8;
    c.camera.realtime = false;
    c.camera.preview_fps = preview_fps;
    c.storage.data_dir = dir_ / "data";
    c.session.guide_file = dir_ / "guide.json";
    c.http.port = 0;
    return c;
  }
  std::unique_ptr<Daemon> make(const DaemonConfig& c) {
    DaemonOptions o;
    o.handle_signals = false;
    auto d = Daemon::create(c, o);
    EXPECT_TRUE(d) << (d ? "" : d.error().message);
    return d ? std::move(*d) : nullptr;
  }
  // Waits until the status satisfies `pred`, at most `max_waits` x 100 ms (a hang is a bug).
  template <class P>
  nlohmann::json wait_for(Daemon& d, P pred, int max_waits = 600) {
    std::uint64_t v = 0;
    for (int i = 0; i < max_waits; ++i) {
      auto s = d.status();
      if (pred(s)) return s;
      v = d.wait_status(v, std::chrono::milliseconds(100));
    }
    ADD_FAILURE() << "condition never held; last status " << d.status().dump();
    return d.status();
  }

  // The store as `facebooth store info --verify` sees it (read-only).
  Result<SessionStore> open_store() const {
    StoreOptions ro;
    ro.read_only = true;
    return SessionStore::open(dir_ / "data" / "store", ro);
  }
  // The store verifies and no partial (temporary) file is left anywhere in the data folder.
  void expect_store_consistent() const {
    auto store = open_store();
    ASSERT_TRUE(store) << store.error().message;
    auto report = store->verify();
    ASSERT_TRUE(report) << report.error().message;
    EXPECT_TRUE(report->ok()) << report->integrity << " " << report->problems.size();
    for (const auto& e : std::filesystem::recursive_directory_iterator(dir_ / "data")) {
      const std::string name = e.path().filename().string();
      EXPECT_NE(name.rfind(kDurableTempPrefix, 0), 0u) << "partial file left: " << e.path();
    }
  }

  // The store holds one session, complete or not, with `done` captures done (unchecked when
  // nullopt); its id goes to `id` when given.
  void expect_one_session(bool complete, std::optional<int> done,
                          std::int64_t* id = nullptr) const {
    auto store = open_store();
    ASSERT_TRUE(store) << store.error().message;
    auto sessions = store->sessions();
    ASSERT_TRUE(sessions) << sessions.error().message;
    ASSERT_EQ(sessions->size(), 1u);
    EXPECT_EQ(sessions->front().complete, complete);
    if (done) {
      EXPECT_EQ(sessions->front().done_count, *done);
    }
    if (id != nullptr) *id = sessions->front().id;
  }

  std::filesystem::path dir_;

 private:
  std::string prefix_, guide_json_;
};

}  // namespace fb::test
