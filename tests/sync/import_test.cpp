// SessionStore::import_session (what `facebooth sync` stores): one durable step. A failed write
// or a SIGKILL at any point of the import leaves the store as it was (verify() passes, no
// session, no subject, the orphaned files removed at the next open); a finished import reads
// back exactly; the booth's ids key it, so the same session is never imported twice and two
// booths' equal ids never collide.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>

#include "storage/session_store.hpp"

namespace fb {
namespace {

namespace fs = std::filesystem;

SessionImport sample(const std::string& booth, std::int64_t session, int captures = 3) {
  SessionImport in;
  in.booth = booth;
  in.origin_session = session;
  in.origin_subject = 1;
  in.subject_name = "Ada";
  in.calibration_json = R"({"serial": "unit-1"})";
  for (int i = 0; i < captures; ++i) {
    ImportedCapture c;
    c.index = i;
    c.expression = i == 0 ? "neutral" : "smile" + std::to_string(i);
    c.state = CaptureState::kDone;
    c.attempts = 1;
    c.qa_scores = {{"fit_rms_mm", 0.5 + i}};
    RgbdFrame f;
    f.color.resize(16, 8);
    for (std::size_t p = 0; p < f.color.pixels.size(); ++p)
      f.color.pixels[p] = {static_cast<std::uint8_t>(p), static_cast<std::uint8_t>(i), 7};
    c.frames.push_back(f);
    c.fused_depth.resize(16, 8);
    for (std::size_t p = 0; p < c.fused_depth.pixels.size(); ++p)
      c.fused_depth.pixels[p] = static_cast<std::uint16_t>(800 + p + i);
    c.landmarks = {{1.5f, 2.5f, true, 1, 2, 800}, {3.5f, 4.5f, false, 0, 0, 0}};
    c.landmark_source = i == 2 ? LandmarkSource::kOperator : LandmarkSource::kAutomatic;
    c.mesh = MeshData{{0, 0, 0, 1, 0, float(i), 0, 1, 0}, {0, 1, 2}};
    c.mesh_role = i == 0 ? MeshRole::kNeutral : MeshRole::kFitted;
    in.captures.push_back(std::move(c));
  }
  return in;
}

class ImportTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("fb-import-test-" + std::to_string(::getpid()) + "-" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(ImportTest, AnImportReadsBackAndIsKeyedByTheBooth) {
  auto store = SessionStore::open(dir_);
  ASSERT_TRUE(store) << store.error().message;
  auto id = store->import_session(sample("booth-a", 1));
  ASSERT_TRUE(id) << id.error().message;
  // The other booth's session 1 of subject 1 is another session and another subject.
  auto other = store->import_session(sample("booth-b", 1));
  ASSERT_TRUE(other) << other.error().message;
  EXPECT_NE(*id, *other);
  // Booth A's next session of the same subject joins that subject.
  auto second = store->import_session(sample("booth-a", 2));
  ASSERT_TRUE(second);
  auto again = store->import_session(sample("booth-a", 1));
  ASSERT_FALSE(again);
  EXPECT_NE(again.error().message.find("already in this store as session " + std::to_string(*id)),
            std::string::npos)
      << again.error().message;
  EXPECT_EQ(store->subjects()->size(), 2u);
  EXPECT_EQ(store->session(*second)->subject, store->session(*id)->subject);
  EXPECT_EQ(*store->imported_session("booth-b", 1), std::optional<SessionId>(*other));
  EXPECT_FALSE(*store->imported_session("booth-b", 2));

  auto s = store->session(*id);
  ASSERT_TRUE(s);
  EXPECT_TRUE(s->complete);
  EXPECT_EQ(s->done_count, 3);
  EXPECT_EQ(s->origin_booth, "booth-a");
  EXPECT_EQ(s->origin_session, 1);
  EXPECT_EQ(s->calibration_json, R"({"serial": "unit-1"})");
  const SessionImport want = sample("booth-a", 1);
  for (int i = 0; i < 3; ++i) {
    auto c = store->read_capture(*id, i);
    ASSERT_TRUE(c) << c.error().message;
    const ImportedCapture& w = want.captures[static_cast<std::size_t>(i)];
    EXPECT_EQ(c->info.expression, w.expression);
    EXPECT_EQ(c->info.attempts, 1);
    EXPECT_DOUBLE_EQ(c->info.qa_scores.at("fit_rms_mm"), 0.5 + i);
    ASSERT_EQ(c->frames.size(), 1u);
    EXPECT_EQ(c->frames[0].color.pixels.size(), w.frames[0].color.pixels.size());
    EXPECT_TRUE(std::equal(c->frames[0].color.pixels.begin(), c->frames[0].color.pixels.end(),
                           w.frames[0].color.pixels.begin(),
                           [](Rgb8 a, Rgb8 b) { return a.r == b.r && a.g == b.g && a.b == b.b; }));
    EXPECT_EQ(c->fused_depth.pixels, w.fused_depth.pixels);
    ASSERT_EQ(c->landmarks.size(), 2u);
    EXPECT_FLOAT_EQ(c->landmarks[0].z, 800);
    EXPECT_EQ(c->landmark_source, w.landmark_source);
  }
  auto meshes = store->meshes(*id);
  ASSERT_EQ(meshes->size(), 3u);
  EXPECT_EQ((*meshes)[0].role, MeshRole::kNeutral);
  EXPECT_EQ(store->read_mesh((*meshes)[2].id)->positions, want.captures[2].mesh->positions);
  auto verify = store->verify();
  ASSERT_TRUE(verify);
  EXPECT_TRUE(verify->ok());
}

TEST_F(ImportTest, AFailedWriteLeavesNothing) {
  for (int failing_write : {1, 4, 9}) {
    int writes = 0;
    StoreOptions o;
    o.inject_write_error = [&](std::size_t bytes) {
      return bytes == 0 && ++writes == failing_write ? ENOSPC : 0;
    };
    {
      auto store = SessionStore::open(dir_, o);
      ASSERT_TRUE(store) << store.error().message;
      auto id = store->import_session(sample("booth-a", 1));
      ASSERT_FALSE(id) << "write " << failing_write;
      EXPECT_NE(id.error().message.find("nothing was stored"), std::string::npos)
          << id.error().message;
      EXPECT_EQ(store->sessions()->size(), 0u);
      EXPECT_EQ(store->subjects()->size(), 0u);
      EXPECT_FALSE(*store->imported_session("booth-a", 1));
    }
    auto store = SessionStore::open(dir_);
    ASSERT_TRUE(store);
    EXPECT_TRUE(store->verify()->ok());
    std::size_t files = 0;
    for (auto& e : fs::recursive_directory_iterator(dir_ / "sessions"))
      files += e.is_regular_file();
    EXPECT_EQ(files, 0u) << "write " << failing_write;
  }
  // And then the same import succeeds.
  auto store = SessionStore::open(dir_);
  ASSERT_TRUE(store->import_session(sample("booth-a", 1)));
}

// A SIGKILL at each step of the import protocol (writing, syncing, renaming a file, the
// commit): after it the store opens clean, with nothing or everything of the session.
TEST_F(ImportTest, SigkillAtAnyPhaseLeavesTheStoreAsItWasOrComplete) {
  int killed = 0;
  for (int step = 1; step <= 40; step += 3) {
    fs::remove_all(dir_);
    const pid_t pid = ::fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
      int phases = 0;
      StoreOptions o;
      o.on_phase = [&](StorePhase p) {
        if (p != StorePhase::kIdle && ++phases == step) ::raise(SIGKILL);
      };
      auto store = SessionStore::open(dir_, o);
      if (!store) std::_Exit(2);
      phases = 0;  // count the import's phases only
      std::_Exit(store->import_session(sample("booth-a", 1)) ? 0 : 3);
    }
    int status = 0;
    ::waitpid(pid, &status, 0);
    const bool was_killed = WIFSIGNALED(status);
    killed += was_killed;
    auto store = SessionStore::open(dir_);
    ASSERT_TRUE(store) << store.error().message;
    auto verify = store->verify();
    ASSERT_TRUE(verify);
    EXPECT_TRUE(verify->ok()) << "step " << step;
    const auto sessions = store->sessions()->size();
    if (was_killed) {
      EXPECT_LE(sessions, 1u);
      if (sessions == 0) {
        EXPECT_EQ(store->subjects()->size(), 0u) << "step " << step;
      }
    } else {
      EXPECT_EQ(sessions, 1u) << "step " << step;
    }
    if (sessions == 1) {
      EXPECT_EQ(store->sessions()->front().done_count, 3);
    }
  }
  EXPECT_GE(killed, 5);  // the kills landed inside the import
}

}  // namespace
}  // namespace fb
