// Bad input: a store from a newer facebooth, garbage and damaged database files, a database of
// another application, a missing session folder, a damaged data file and a full disk. Each one
// gives a clear error and loses nothing already stored.
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <cerrno>
#include <fstream>

#include "sim/crash/crash_trials.hpp"
#include "storage/data_codec.hpp"
#include "storage/durable_file.hpp"
#include "storage/session_store.hpp"
#include "tests/storage/test_dir.hpp"

namespace fb {
namespace {

namespace fs = std::filesystem;
constexpr int kFrames = 3, kW = 32, kH = 24;

std::string file_sha(const fs::path& p) {
  return *sha256_file(p);
}

bool contains(const std::string& s, const std::string& part) {
  return s.find(part) != std::string::npos;
}

Result<void> capture(SessionStore& store, SessionId s, int index) {
  if (auto r = store.begin_capture(s, index); !r) return r;
  return store.commit_capture(s, index, make_test_capture(s, index, kFrames, kW, kH));
}

// A store with one subject, a 4-capture session and its first two captures done.
SessionId make_store(const fs::path& root) {
  auto store = SessionStore::open(root);
  EXPECT_TRUE(store);
  auto session = store->create_session(*store->add_subject("s"), {"a", "b", "c", "d"});
  EXPECT_TRUE(capture(*store, *session, 0));
  EXPECT_TRUE(capture(*store, *session, 1));
  return *session;
}

void set_user_version(const fs::path& db_path, int version) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(db_path.c_str(), &db), SQLITE_OK);
  const std::string sql = "PRAGMA user_version=" + std::to_string(version);
  EXPECT_EQ(sqlite3_exec(db, sql.c_str(), nullptr, nullptr, nullptr), SQLITE_OK);
  sqlite3_close(db);
}

TEST(BadInput, NewerSchemaIsRefusedAndUntouched) {
  test::ScratchDir dir;
  make_store(dir.path());
  const fs::path db = dir.path() / kSessionStoreDatabaseName;
  set_user_version(db, kSessionStoreSchemaVersion + 5);
  const std::string before = file_sha(db);
  auto store = SessionStore::open(dir.path());
  ASSERT_FALSE(store);
  EXPECT_TRUE(contains(store.error().message, "newer")) << store.error().message;
  EXPECT_TRUE(contains(store.error().message, "update facebooth")) << store.error().message;
  StoreOptions ro;
  ro.read_only = true;
  EXPECT_FALSE(SessionStore::open(dir.path(), ro));
  EXPECT_EQ(file_sha(db), before);
  // Session data files were not treated as orphans.
  EXPECT_EQ(std::distance(fs::directory_iterator(dir.path() / "sessions" / "1"),
                          fs::directory_iterator()),
            4);
}

TEST(BadInput, GarbageDatabaseFileIsRefusedAndUntouched) {
  test::ScratchDir dir;
  const fs::path db = dir.path() / kSessionStoreDatabaseName;
  {
    std::ofstream out(db, std::ios::binary);
    for (int i = 0; i < 10000; ++i) out.put(static_cast<char>((i * 7919) & 0xff));
  }
  const std::string before = file_sha(db);
  auto store = SessionStore::open(dir.path());
  ASSERT_FALSE(store);
  EXPECT_TRUE(contains(store.error().message, "not an SQLite database")) << store.error().message;
  EXPECT_TRUE(contains(store.error().message, "restore it from a backup"));
  EXPECT_EQ(file_sha(db), before);
  EXPECT_FALSE(fs::exists(dir.path() / "facebooth.db-wal"));
}

TEST(BadInput, DamagedPagesAreReportedAndUntouched) {
  test::ScratchDir dir;
  make_store(dir.path());
  const fs::path db = dir.path() / kSessionStoreDatabaseName;
  // Checkpointed by the clean close; now scribble over everything after the first page.
  const auto size = fs::file_size(db);
  ASSERT_GT(size, 8192u);
  {
    std::fstream io(db, std::ios::binary | std::ios::in | std::ios::out);
    io.seekp(4096);
    for (std::uintmax_t i = 4096; i < size; ++i) io.put(static_cast<char>(0xA5 ^ (i & 0x3f)));
  }
  const std::string before = file_sha(db);
  auto store = SessionStore::open(dir.path());
  ASSERT_FALSE(store);
  EXPECT_TRUE(contains(store.error().message, "damaged") ||
              contains(store.error().message, "malformed"))
      << store.error().message;
  EXPECT_TRUE(contains(store.error().message, "backup")) << store.error().message;
  EXPECT_EQ(file_sha(db), before);
}

TEST(BadInput, ForeignSqliteDatabaseIsRefused) {
  test::ScratchDir dir;
  const fs::path db = dir.path() / kSessionStoreDatabaseName;
  sqlite3* raw = nullptr;
  ASSERT_EQ(sqlite3_open(db.c_str(), &raw), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(raw, "CREATE TABLE photos(x); INSERT INTO photos VALUES(1);", nullptr,
                         nullptr, nullptr),
            SQLITE_OK);
  sqlite3_close(raw);
  const std::string before = file_sha(db);
  auto store = SessionStore::open(dir.path());
  ASSERT_FALSE(store);
  EXPECT_TRUE(contains(store.error().message, "not a facebooth session store"))
      << store.error().message;
  EXPECT_EQ(file_sha(db), before);
}

TEST(BadInput, MissingStoreFolderForReaders) {
  test::ScratchDir dir;
  StoreOptions ro;
  ro.read_only = true;
  auto store = SessionStore::open(dir.path() / "nope", ro);
  ASSERT_FALSE(store);
  EXPECT_TRUE(contains(store.error().message, "no session store")) << store.error().message;
}

TEST(BadInput, MissingSessionFolderLosesNothing) {
  test::ScratchDir dir;
  const SessionId session = make_store(dir.path());
  const fs::path folder = dir.path() / "sessions" / std::to_string(session);
  const fs::path moved = dir.path() / "moved-away";
  fs::rename(folder, moved);
  {
    auto store = SessionStore::open(dir.path());
    ASSERT_TRUE(store) << store.error().message;
    EXPECT_EQ(store->orphans_removed(), 0);
    auto read = store->read_capture(session, 0);
    ASSERT_FALSE(read);
    EXPECT_TRUE(contains(read.error().message, "missing")) << read.error().message;
    EXPECT_TRUE(contains(read.error().message, "restore")) << read.error().message;
    auto write = capture(*store, session, 2);
    ASSERT_FALSE(write);
    EXPECT_TRUE(contains(write.error().message, "missing")) << write.error().message;
    EXPECT_EQ((*store->next_capture(session))->index, 2);
    auto report = store->verify();
    ASSERT_TRUE(report);
    EXPECT_EQ(report->problems.size(), 4u);
  }
  fs::rename(moved, folder);
  auto store = SessionStore::open(dir.path());
  ASSERT_TRUE(store);
  for (int i = 0; i < 2; ++i) {
    auto data = store->read_capture(session, i);
    ASSERT_TRUE(data) << data.error().message;
    EXPECT_EQ(compare_test_capture(*data, session, i, kFrames, kW, kH), "");
  }
  EXPECT_TRUE(capture(*store, session, 2));
  EXPECT_TRUE(store->verify()->ok());
}

TEST(BadInput, DamagedDataFileIsDetectedOthersStillRead) {
  test::ScratchDir dir;
  const SessionId session = make_store(dir.path());
  const fs::path folder = dir.path() / "sessions" / std::to_string(session);
  // Overwrites one byte of capture `index`'s frame file, `from_end` bytes before its end or at
  // byte 200 (inside the first frame).
  auto damage = [&](int index, std::uintmax_t from_end) {
    for (const auto& e : fs::directory_iterator(folder)) {
      const std::string name = e.path().filename().string();
      if (name.rfind("c" + std::to_string(index) + "-", 0) == 0 &&
          name.find("frames") != std::string::npos) {
        std::fstream io(e.path(), std::ios::binary | std::ios::in | std::ios::out);
        io.seekp(static_cast<std::streamoff>(from_end ? fs::file_size(e.path()) - from_end : 200));
        io.put('\x7f');
      }
    }
  };
  damage(0, 0);
  auto store = SessionStore::open(dir.path());
  ASSERT_TRUE(store);
  auto bad = store->read_capture(session, 0);
  ASSERT_FALSE(bad);
  EXPECT_TRUE(contains(bad.error().message, "damaged")) << bad.error().message;
  EXPECT_TRUE(store->read_capture(session, 1));
  // Damage in a frame that is not decoded is found too (the whole file is hashed).
  damage(1, 5);
  auto bad_tail = store->read_capture(session, 1, {.max_frames = 1});
  ASSERT_FALSE(bad_tail);
  EXPECT_TRUE(contains(bad_tail.error().message, "damaged")) << bad_tail.error().message;
  EXPECT_EQ(store->verify()->problems.size(), 2u);
}

TEST(BadInput, FullDiskDuringCaptureLosesNothing) {
  test::ScratchDir dir;
  const SessionId session = make_store(dir.path());
  // The disk "fills up" part-way through each data file in turn: the frame sequence, then the
  // fused depth map (the second file of a capture, after the first one was already renamed).
  for (std::size_t fail_after : {std::size_t{0}, std::size_t{5000}, std::size_t{1000000}}) {
    StoreOptions full;
    int files_started = 0;
    full.inject_write_error = [&](std::size_t written) {
      if (written == 0) ++files_started;
      if (fail_after == 1000000) return files_started >= 2 ? ENOSPC : 0;  // the fused map
      return written >= fail_after ? ENOSPC : 0;
    };
    auto store = SessionStore::open(dir.path(), full);
    ASSERT_TRUE(store);
    auto r = capture(*store, session, 2);
    ASSERT_FALSE(r);
    EXPECT_TRUE(contains(r.error().message, "no space left")) << r.error().message;
    EXPECT_TRUE(contains(r.error().message, "free space")) << r.error().message;
    EXPECT_EQ((*store->next_capture(session))->index, 2);
    for (int i = 0; i < 2; ++i) {
      auto data = store->read_capture(session, i);
      ASSERT_TRUE(data) << data.error().message;
      EXPECT_EQ(compare_test_capture(*data, session, i, kFrames, kW, kH), "");
    }
    // Nothing of the failed capture is left behind: 2 done captures x 2 files.
    int files = 0;
    for (const auto& e :
         fs::directory_iterator(dir.path() / "sessions" / std::to_string(session))) {
      (void)e;
      ++files;
    }
    EXPECT_EQ(files, 4) << "fail_after " << fail_after;
  }
  // With space again, the same capture goes through.
  auto store = SessionStore::open(dir.path());
  ASSERT_TRUE(store);
  EXPECT_EQ(store->orphans_removed(), 0);
  ASSERT_TRUE(capture(*store, session, 2));
  EXPECT_TRUE(store->verify()->ok());
  EXPECT_EQ(store->capture(session, 2)->attempts, 4);
}

// Found by review while writing store_files_fuzz: a mesh or rig file whose triangles point
// past its vertices (add_mesh never writes one; a file written wrong whose checksum matches)
// was returned as is, and the exporters index positions with those triangles.
TEST(BadInput, MeshAndRigFilesWithTrianglesPastTheirVerticesAreMalformed) {
  using namespace store_detail;
  auto mesh_file = [](std::uint32_t corner) {
    ByteWriter w;
    w.put_magic(kMeshMagic);
    w.put(std::uint32_t{3});
    w.put(std::uint32_t{1});
    w.put_span(std::span<const float>(std::vector<float>(9, 1.0f)));
    w.put_span(std::span<const std::uint32_t>(std::vector<std::uint32_t>{0, 1, corner}));
    return w.bytes;
  };
  MeshData mesh;
  EXPECT_TRUE(decode_mesh(mesh_file(2), mesh));
  EXPECT_FALSE(decode_mesh(mesh_file(3), mesh));
  ByteWriter rig;
  rig.put_magic(kRigMagic);
  rig.put(std::uint32_t{3});
  rig.put(std::uint32_t{1});
  rig.put(std::uint32_t{0});
  rig.put_span(std::span<const float>(std::vector<float>(9, 1.0f)));
  rig.put_span(std::span<const std::uint32_t>(std::vector<std::uint32_t>{0, 1, 7}));
  RigData decoded;
  EXPECT_FALSE(decode_rig(rig.bytes, decoded));
}

}  // namespace
}  // namespace fb
