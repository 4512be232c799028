// Session store round trips: captures, resume, rejections, landmarks, meshes, rigs, models,
// takes, migrations, orphan cleanup and the one-writer/many-readers thread model.
#include <gtest/gtest.h>

#include <sqlite3.h>
#include <cerrno>
#include <cmath>

#include <atomic>
#include <cstring>
#include <fstream>
#include <thread>

#include "sim/crash/crash_trials.hpp"
#include "storage/session_store.hpp"
#include "storage/sha256.hpp"
#include "storage/take_writer.hpp"
#include "tests/storage/test_dir.hpp"

namespace fb {
namespace {

namespace fs = std::filesystem;
constexpr int kFrames = 3, kW = 32, kH = 24;

std::vector<std::string> guide(int n) {
  std::vector<std::string> g;
  for (int i = 0; i < n; ++i) g.push_back("expr" + std::to_string(i));
  return g;
}

Result<void> capture(SessionStore& store, SessionId s, int index) {
  if (auto r = store.begin_capture(s, index); !r) return r;
  return store.commit_capture(s, index, make_test_capture(s, index, kFrames, kW, kH));
}

TEST(SessionStore, CommitReadResumeAndComplete) {
  test::ScratchDir dir;
  auto store = SessionStore::open(dir.path());
  ASSERT_TRUE(store) << store.error().message;
  EXPECT_EQ(store->schema_version(), kSessionStoreSchemaVersion);
  auto subject = store->add_subject("alice");
  ASSERT_TRUE(subject);
  auto session = store->create_session(*subject, guide(3));
  ASSERT_TRUE(session) << session.error().message;

  auto next = store->next_capture(*session);
  ASSERT_TRUE(next && *next);
  EXPECT_EQ((*next)->index, 0);
  EXPECT_EQ((*next)->expression, "expr0");
  ASSERT_TRUE(capture(*store, *session, 0));
  next = store->next_capture(*session);
  ASSERT_TRUE(next && *next);
  EXPECT_EQ((*next)->index, 1);

  auto data = store->read_capture(*session, 0);
  ASSERT_TRUE(data) << data.error().message;
  EXPECT_EQ(compare_test_capture(*data, *session, 0, kFrames, kW, kH), "");
  EXPECT_EQ(data->info.state, CaptureState::kDone);
  EXPECT_EQ(data->info.attempts, 1);
  EXPECT_EQ(data->info.frame_count, kFrames);
  EXPECT_FALSE(data->info.completed_at.empty());

  // Reading only the first frame (what exports need) gives that frame exactly, the stored count
  // in info, and still verifies the whole file.
  auto first = store->read_capture(*session, 0, {.max_frames = 1});
  ASSERT_TRUE(first) << first.error().message;
  ASSERT_EQ(first->frames.size(), 1u);
  EXPECT_EQ(first->info.frame_count, kFrames);
  EXPECT_EQ(first->frames[0].index, data->frames[0].index);
  EXPECT_EQ(first->frames[0].depth_mm.pixels, data->frames[0].depth_mm.pixels);
  EXPECT_EQ(first->frames[0].raw_disparity.pixels, data->frames[0].raw_disparity.pixels);
  ASSERT_EQ(first->frames[0].color.pixels.size(), data->frames[0].color.pixels.size());
  EXPECT_EQ(std::memcmp(first->frames[0].color.pixels.data(), data->frames[0].color.pixels.data(),
                        data->frames[0].color.pixels.size() * sizeof(Rgb8)),
            0);
  EXPECT_EQ(first->fused_depth.pixels, data->fused_depth.pixels);
  EXPECT_EQ(store->read_capture(*session, 0, {.max_frames = 0})->frames.size(), 0u);

  // Committing a done capture again is refused and changes nothing.
  auto again = store->commit_capture(*session, 0, make_test_capture(*session, 0, 1, 4, 4));
  ASSERT_FALSE(again);
  EXPECT_NE(again.error().message.find("already done"), std::string::npos);
  EXPECT_EQ(store->read_capture(*session, 0)->frames.size(), std::size_t{kFrames});

  // A reopened store resumes at the same place.
  store = Result<SessionStore>(fail("closed"));
  auto reopened = SessionStore::open(dir.path());
  ASSERT_TRUE(reopened) << reopened.error().message;
  EXPECT_EQ(reopened->orphans_removed(), 0);
  next = reopened->next_capture(*session);
  ASSERT_TRUE(next && *next);
  EXPECT_EQ((*next)->index, 1);
  ASSERT_TRUE(capture(*reopened, *session, 1));
  ASSERT_TRUE(capture(*reopened, *session, 2));
  next = reopened->next_capture(*session);
  ASSERT_TRUE(next);
  EXPECT_FALSE(next->has_value());
  auto info = reopened->session(*session);
  ASSERT_TRUE(info);
  EXPECT_TRUE(info->complete);
  EXPECT_EQ(info->done_count, 3);
  auto report = reopened->verify();
  ASSERT_TRUE(report);
  EXPECT_TRUE(report->ok()) << report->integrity;
  EXPECT_EQ(report->files_checked, 6);
}

TEST(SessionStore, RejectedCaptureIsRetakenAndAttemptsCount) {
  test::ScratchDir dir;
  auto store = SessionStore::open(dir.path());
  ASSERT_TRUE(store);
  auto session = store->create_session(*store->add_subject("bob"), guide(2));
  ASSERT_TRUE(session);
  ASSERT_TRUE(store->begin_capture(*session, 0));
  ASSERT_TRUE(store->reject_capture(*session, 0, {{"landmark_confidence", 0.2}}));
  auto c = store->capture(*session, 0);
  ASSERT_TRUE(c);
  EXPECT_EQ(c->state, CaptureState::kRejected);
  EXPECT_DOUBLE_EQ(c->qa_scores.at("landmark_confidence"), 0.2);
  EXPECT_EQ((*store->next_capture(*session))->index, 0);
  ASSERT_TRUE(capture(*store, *session, 0));
  c = store->capture(*session, 0);
  EXPECT_EQ(c->attempts, 2);
  EXPECT_EQ(c->state, CaptureState::kDone);
  EXPECT_FALSE(store->reject_capture(*session, 0, {}));
}

TEST(SessionStore, OperatorLandmarksReplaceAutomaticOnes) {
  test::ScratchDir dir;
  auto store = SessionStore::open(dir.path());
  ASSERT_TRUE(store);
  auto session = store->create_session(*store->add_subject("c"), guide(1));
  ASSERT_FALSE(store->set_operator_landmarks(*session, 0, {}));  // not done yet
  ASSERT_TRUE(capture(*store, *session, 0));
  auto before = store->read_capture(*session, 0);
  ASSERT_TRUE(before);
  EXPECT_EQ(before->landmark_source, LandmarkSource::kAutomatic);
  std::vector<Landmark> moved = before->landmarks;
  moved[30].u += 5.0f;
  ASSERT_TRUE(store->set_operator_landmarks(*session, 0, moved));
  moved[30].u += 1.0f;
  ASSERT_TRUE(store->set_operator_landmarks(*session, 0, moved));  // replaces, not duplicates
  auto after = store->read_capture(*session, 0);
  ASSERT_TRUE(after);
  EXPECT_EQ(after->landmark_source, LandmarkSource::kOperator);
  EXPECT_FLOAT_EQ(after->landmarks[30].u, before->landmarks[30].u + 6.0f);
  EXPECT_EQ(after->landmarks.size(), before->landmarks.size());
}

TEST(SessionStore, MeshesRigsModelsAndTakesRoundTrip) {
  test::ScratchDir dir;
  auto store = SessionStore::open(dir.path());
  ASSERT_TRUE(store);
  auto subject = store->add_subject("d");
  auto session = store->create_session(*subject, guide(1));
  ASSERT_TRUE(session);
  MeshData mesh{{0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0.5f}, {0, 1, 2, 1, 3, 2}};
  auto mesh_id = store->add_mesh(*session, 0, MeshRole::kFitted, "pose_0", mesh);
  ASSERT_TRUE(mesh_id) << mesh_id.error().message;
  auto back = store->read_mesh(*mesh_id);
  ASSERT_TRUE(back);
  EXPECT_EQ(back->positions, mesh.positions);
  EXPECT_EQ(back->triangles, mesh.triangles);
  auto listed = store->meshes(*session);
  ASSERT_TRUE(listed);
  ASSERT_EQ(listed->size(), 1u);
  EXPECT_EQ(listed->front().name, "pose_0");
  EXPECT_EQ(listed->front().capture_index, 0);
  EXPECT_EQ(listed->front().triangle_count, 2);
  // Bad meshes are refused before anything is written.
  EXPECT_FALSE(
      store->add_mesh(*session, std::nullopt, MeshRole::kScan, "bad", {{0, 0, 0}, {0, 1, 2}}));

  RigData rig;
  rig.neutral = mesh.positions;
  rig.triangles = mesh.triangles;
  rig.shapes = {mesh.positions, mesh.positions};
  rig.shapes[1][2] = 3.0f;
  rig.shape_names = {"jawOpen", "mouthSmile_L"};
  auto rig_id = store->add_rig(*subject, *session, rig);
  ASSERT_TRUE(rig_id) << rig_id.error().message;
  auto rig_back = store->read_rig(*rig_id);
  ASSERT_TRUE(rig_back);
  EXPECT_EQ(rig_back->shapes, rig.shapes);
  EXPECT_EQ(rig_back->shape_names, rig.shape_names);
  auto rigs = store->rigs(*subject);
  ASSERT_TRUE(rigs);
  ASSERT_EQ(rigs->size(), 1u);
  EXPECT_EQ(rigs->front().session, *session);

  const std::vector<std::uint8_t> model_bytes = {1, 2, 3, 4, 5};
  auto model = store->add_model("bilinear", R"({"identities":1})", model_bytes);
  ASSERT_TRUE(model);
  EXPECT_EQ(*store->read_model(*model), model_bytes);
  EXPECT_EQ(store->models()->front().bytes, 5);

  // Takes go through the one writer: times from the first frame, unit quaternions.
  TakeWriter writer({"jawOpen"}, 30.0);
  RigidPose pose;
  pose.translation = Eigen::Vector3d(1, 2, 700);
  pose.rotation = Eigen::Quaterniond(2, 0, 0, 0);  // not normalised by the caller
  ASSERT_TRUE(writer.add_frame(100.0, pose, std::vector<float>{0.5f}));
  ASSERT_TRUE(writer.add_frame(100.04, pose, std::vector<float>{0.75f}));
  EXPECT_FALSE(writer.add_frame(100.08, pose, std::vector<float>{0.5f, 0.5f}));  // 2 for 1 shape
  auto take_id = writer.store(*store, *subject, *session);
  ASSERT_TRUE(take_id) << take_id.error().message;
  auto take_back = store->read_take(*take_id);
  ASSERT_TRUE(take_back) << take_back.error().message;
  EXPECT_EQ(take_back->info.frame_count, 2);
  EXPECT_EQ(take_back->info.session, *session);
  EXPECT_EQ(take_back->info.shape_names, std::vector<std::string>{"jawOpen"});
  ASSERT_EQ(take_back->times_s.size(), 2u);
  EXPECT_DOUBLE_EQ(take_back->times_s[0], 0.0);
  EXPECT_NEAR(take_back->times_s[1], 0.04, 1e-9);
  EXPECT_EQ(take_back->values,
            (std::vector<float>{1, 2, 700, 0, 0, 0, 1, 0.5f, 1, 2, 700, 0, 0, 0, 1, 0.75f}));
  TakeData bad = *take_back;
  bad.times_s.pop_back();  // one time short
  EXPECT_FALSE(store->add_take(bad));
  EXPECT_TRUE(store->verify()->ok());
}

TEST(SessionStore, OneWriterManyReaders) {
  test::ScratchDir dir;
  auto writer = SessionStore::open(dir.path());
  ASSERT_TRUE(writer);
  auto session = writer->create_session(*writer->add_subject("e"), guide(12));
  ASSERT_TRUE(session);
  // A second writer (here in the same process, normally another process) is refused.
  auto second = SessionStore::open(dir.path());
  ASSERT_FALSE(second);
  EXPECT_NE(second.error().message.find("another facebooth process"), std::string::npos);

  // Readers on their own threads and connections see only committed, complete captures while
  // the writer keeps committing.
  std::atomic<bool> stop{false};
  std::atomic<int> reads{0}, errors{0};
  std::vector<std::thread> readers;
  std::vector<std::string> messages(2);
  for (int t = 0; t < 2; ++t) {
    readers.emplace_back([&, t] {
      StoreOptions ro;
      ro.read_only = true;
      auto reader = SessionStore::open(dir.path(), ro);
      if (!reader) {
        messages[t] = reader.error().message;
        ++errors;
        return;
      }
      EXPECT_FALSE(reader->add_subject("nope"));
      while (!stop) {
        auto caps = reader->captures(*session);
        if (!caps) {
          messages[t] = caps.error().message;
          ++errors;
          continue;
        }
        for (const auto& c : *caps) {
          if (c.state != CaptureState::kDone) continue;
          auto data = reader->read_capture(*session, c.index);
          if (!data || !compare_test_capture(*data, *session, c.index, kFrames, kW, kH).empty()) {
            messages[t] = data ? "content differs" : data.error().message;
            ++errors;
          }
          ++reads;
        }
      }
    });
  }
  for (int i = 0; i < 12; ++i) ASSERT_TRUE(capture(*writer, *session, i));
  stop = true;
  for (auto& r : readers) r.join();
  EXPECT_EQ(errors.load(), 0) << messages[0] << " / " << messages[1];
  EXPECT_GT(reads.load(), 0);
}

TEST(SessionStore, MigratesAnOlderSchemaKeepingData) {
  test::ScratchDir dir;
  SessionId session = 0;
  {
    StoreOptions v1;
    v1.migrate_to = 1;
    auto store = SessionStore::open(dir.path(), v1);
    ASSERT_TRUE(store);
    EXPECT_EQ(store->schema_version(), 1);
    session = *store->create_session(*store->add_subject("old"), guide(2));
    ASSERT_TRUE(capture(*store, session, 0));
  }
  {
    StoreOptions ro;
    ro.read_only = true;
    auto reader = SessionStore::open(dir.path(), ro);
    ASSERT_FALSE(reader);  // readers never migrate
    EXPECT_NE(reader.error().message.find("migrate"), std::string::npos);
  }
  auto store = SessionStore::open(dir.path());
  ASSERT_TRUE(store) << store.error().message;
  EXPECT_EQ(store->schema_version(), kSessionStoreSchemaVersion);
  EXPECT_TRUE(store->read_capture(session, 0));
  TakeWriter take({}, 30.0);
  ASSERT_TRUE(take.add_frame(0.0, RigidPose{}, {}));
  EXPECT_TRUE(take.store(*store, store->session(session)->subject, session));
}

// Takes written before schema v3 by the old code paths, rebuilt here byte for byte and row for
// row: the device's (pose + weights, no times) and the host's (a "timestamp_s" pseudo-shape as
// the last column). A reader of the v2 store and, after the writer migrates it, the writer both
// read them in the current layout: the device's times from the frame rate, the host's from its
// column, whose name is gone from the shape list.
TEST(SessionStore, TakesFromBeforeSchemaV3ReadAfterMigration) {
  test::ScratchDir dir;
  SubjectId subject = 0;
  {
    StoreOptions v2;
    v2.migrate_to = 2;
    auto store = SessionStore::open(dir.path(), v2);
    ASSERT_TRUE(store) << store.error().message;
    subject = *store->add_subject("old takes");
  }
  // FBTAK001: magic, frames (u32), stride (u32), frames * stride floats.
  auto old_take = [&](const std::string& name, int frames, int stride, auto value_of) {
    std::vector<std::uint8_t> bytes(8 + 4 + 4);
    std::memcpy(bytes.data(), "FBTAK001", 8);
    const std::uint32_t header[2] = {static_cast<std::uint32_t>(frames),
                                     static_cast<std::uint32_t>(stride)};
    std::memcpy(bytes.data() + 8, header, 8);
    for (int f = 0; f < frames; ++f)
      for (int c = 0; c < stride; ++c) {
        const float v = value_of(f, c);
        const auto* p = reinterpret_cast<const std::uint8_t*>(&v);
        bytes.insert(bytes.end(), p, p + 4);
      }
    const fs::path rel = fs::path("subjects") / std::to_string(subject) / name;
    fs::create_directories(dir.path() / rel.parent_path());
    std::ofstream(dir.path() / rel, std::ios::binary)
        .write(reinterpret_cast<const char*>(bytes.data()),
               static_cast<std::streamsize>(bytes.size()));
    return std::make_pair(rel.generic_string(), bytes);
  };
  // The device: 3 frames of pose (q not normalised: the old daemon did not) + jawOpen, 30 fps.
  const auto device = old_take("take.fbtak-dev", 3, 8, [](int f, int c) {
    return c == 2 ? 700.0f : c == 6 ? 1.0f : c == 7 ? 0.1f * f : 0.0f;
  });
  // The host: pose + jawOpen + timestamp_s (frames 0.000, 0.050, 0.090 s apart, not 1/30).
  const float host_times[3] = {0.0f, 0.05f, 0.09f};
  const auto host = old_take("take.fbtak-host", 3, 9, [&](int f, int c) {
    return c == 8 ? host_times[f] : c == 6 ? 1.0f : c == 7 ? 0.2f : 0.0f;
  });
  {
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open((dir.path() / kSessionStoreDatabaseName).c_str(), &db), SQLITE_OK);
    const std::string sql =
        "INSERT INTO files(id, relpath, bytes, sha256) VALUES(100, '" + device.first + "', " +
        std::to_string(device.second.size()) + ", '" + sha256_hex(device.second) + "'), (101, '" +
        host.first + "', " + std::to_string(host.second.size()) + ", '" + sha256_hex(host.second) +
        "');"
        "INSERT INTO takes(id, subject_id, session_id, fps, shape_names_json, frame_count, "
        "file_id) VALUES(7, " +
        std::to_string(subject) + ", NULL, 30, '[\"jawOpen\"]', 3, 100), (8, " +
        std::to_string(subject) + ", NULL, 30, '[\"jawOpen\",\"timestamp_s\"]', 3, 101);";
    char* error = nullptr;
    EXPECT_EQ(sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &error), SQLITE_OK)
        << (error ? error : "");
    sqlite3_free(error);
    sqlite3_close(db);
  }
  {
    // A reader of the v2 store (readers never migrate) reads both takes the same way.
    StoreOptions ro;
    ro.read_only = true;
    auto reader = SessionStore::open(dir.path(), ro);
    ASSERT_TRUE(reader) << reader.error().message;
    EXPECT_EQ(reader->schema_version(), 2);
    auto listed = reader->takes(subject);
    ASSERT_TRUE(listed) << listed.error().message;
    ASSERT_EQ(listed->size(), 2u);
    EXPECT_EQ(listed->at(1).shape_names, std::vector<std::string>{"jawOpen"});
    auto hst = reader->read_take(8);
    ASSERT_TRUE(hst) << hst.error().message;
    EXPECT_NEAR(hst->times_s[2], 0.09, 1e-7);
    auto dev = reader->read_take(7);
    ASSERT_TRUE(dev) << dev.error().message;
    EXPECT_NEAR(dev->times_s[2], 2.0 / 30.0, 1e-12);
  }
  auto store = SessionStore::open(dir.path());  // the writer migrates v2 -> the newest
  ASSERT_TRUE(store) << store.error().message;
  EXPECT_EQ(store->schema_version(), kSessionStoreSchemaVersion);
  EXPECT_EQ(store->orphans_removed(), 0);  // the old files are referenced, so kept
  auto listed = store->takes(subject);
  ASSERT_TRUE(listed);
  ASSERT_EQ(listed->size(), 2u);
  EXPECT_EQ(listed->at(1).shape_names, std::vector<std::string>{"jawOpen"});  // no timestamp_s

  auto dev = store->read_take(7);
  ASSERT_TRUE(dev) << dev.error().message;
  ASSERT_EQ(dev->values.size(), 3u * 8u);
  EXPECT_EQ(dev->info.stride(), 8);
  EXPECT_FLOAT_EQ(dev->frame(2)[7], 0.2f);
  EXPECT_FLOAT_EQ(dev->frame(2)[2], 700.0f);
  EXPECT_NEAR(dev->times_s[2], 2.0 / 30.0, 1e-12);

  auto hst = store->read_take(8);
  ASSERT_TRUE(hst) << hst.error().message;
  ASSERT_EQ(hst->info.shape_names, std::vector<std::string>{"jawOpen"});
  ASSERT_EQ(hst->values.size(), 3u * 8u);  // the time column moved out of the values
  EXPECT_FLOAT_EQ(hst->frame(1)[7], 0.2f);
  EXPECT_NEAR(hst->times_s[1], 0.05, 1e-7);
  EXPECT_NEAR(hst->times_s[2], 0.09, 1e-7);
  EXPECT_TRUE(store->verify()->ok());

  // New takes in the migrated store use the new layout beside the old ones.
  TakeWriter fresh({"jawOpen"}, 30.0);
  ASSERT_TRUE(fresh.add_frame(5.0, RigidPose{}, std::vector<float>{0.3f}));
  auto id = fresh.store(*store, subject, std::nullopt);
  ASSERT_TRUE(id) << id.error().message;
  EXPECT_FLOAT_EQ(store->read_take(*id)->frame(0)[7], 0.3f);
}

// Which rig serves a session: the newest built from it, else the subject's newest (from another
// session or none); a subject without rigs has none.
// Schema v4: a session's texture atlases (subject and per capture) and the unit calibration its
// frames were taken with survive a reopen and the integrity check; a v3 store gains both.
TEST(SessionStore, TexturesAndSessionCalibrationRoundTrip) {
  test::ScratchDir dir;
  SessionId session = 0;
  {
    StoreOptions v3;
    v3.migrate_to = 3;
    auto store = SessionStore::open(dir.path(), v3);
    ASSERT_TRUE(store);
    session = *store->create_session(*store->add_subject("s"), guide(2));
    ASSERT_TRUE(capture(*store, session, 0));
    const std::vector<std::uint8_t> png = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n', 1, 2};
    auto refused = store->add_texture(session, std::nullopt, 4, 4, png, "{}");
    ASSERT_FALSE(refused);  // schema v3 has no textures table
    EXPECT_NE(refused.error().message.find("migrate"), std::string::npos);
  }
  auto store = SessionStore::open(dir.path());
  ASSERT_TRUE(store) << store.error().message;
  EXPECT_EQ(store->session(session)->calibration_json, "");  // recorded by nothing yet
  ASSERT_TRUE(store->set_session_calibration(session, R"({"unit": 1})"));
  const std::vector<std::uint8_t> subject_png = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n', 7};
  const std::vector<std::uint8_t> capture_png = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n', 8, 9};
  auto a = store->add_texture(session, std::nullopt, 512, 512, subject_png, R"({"views": 15})");
  auto b = store->add_texture(session, 1, 256, 256, capture_png, "{}");
  ASSERT_TRUE(a && b);
  EXPECT_FALSE(store->add_texture(session, 1, 256, 256, std::vector<std::uint8_t>{1, 2, 3}, "{}"));
  EXPECT_FALSE(store->add_texture(99, 1, 256, 256, capture_png, "{}"));
  { SessionStore closing = std::move(*store); }  // one writer at a time
  store = SessionStore::open(dir.path());        // reopen: nothing is an orphan
  ASSERT_TRUE(store);
  EXPECT_EQ(store->orphans_removed(), 0);
  EXPECT_EQ(store->session(session)->calibration_json, R"({"unit": 1})");
  auto listed = store->textures(session);
  ASSERT_TRUE(listed);
  ASSERT_EQ(listed->size(), 2u);
  EXPECT_FALSE(listed->at(0).capture_index);
  EXPECT_EQ(listed->at(0).width, 512);
  EXPECT_EQ(listed->at(0).params_json, R"({"views": 15})");
  EXPECT_EQ(listed->at(1).capture_index, 1);
  EXPECT_EQ(listed->at(1).bytes, static_cast<std::int64_t>(capture_png.size()));
  EXPECT_EQ(*store->read_texture(*a), subject_png);
  EXPECT_EQ(*store->read_texture(*b), capture_png);
  EXPECT_FALSE(store->read_texture(12345));
  auto report = store->verify();
  ASSERT_TRUE(report);
  EXPECT_TRUE(report->ok()) << report->problems.size();
}

// Schema v6: a capture's wrinkle detail (displacement floats + normal PNG, with the rig) round
// trips; a v5 store refuses it until a writer migrates; a write failing on the second file
// leaves neither a row nor a file behind.
TEST(SessionStore, WrinkleDetailRoundTripsAndFailsWhole) {
  test::ScratchDir dir;
  SessionId session = 0;
  WrinkleDetailData detail;
  detail.width = 4;
  detail.height = 2;
  detail.displacement_mm = {0.0f, -0.25f, 0.5f, 0.0f, 1e-3f, 0.0f, -1.0f, 0.0f};
  detail.normal_png = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n', 5, 6, 7};
  {
    StoreOptions v5;
    v5.migrate_to = 5;
    auto store = SessionStore::open(dir.path(), v5);
    ASSERT_TRUE(store);
    session = *store->create_session(*store->add_subject("s"), guide(2));
    auto refused = store->add_wrinkle_detail(session, 1, std::nullopt, detail, "{}");
    ASSERT_FALSE(refused);
    EXPECT_TRUE(store->wrinkle_details(session)->empty());
  }
  {
    // The second data file (the normal map) fails its first write: ENOSPC.
    StoreOptions failing;
    int starts = 0;
    failing.inject_write_error = [&starts](std::size_t written) {
      if (written == 0) ++starts;
      return starts >= 2 ? ENOSPC : 0;
    };
    auto store = SessionStore::open(dir.path(), failing);
    ASSERT_TRUE(store) << store.error().message;
    EXPECT_FALSE(store->add_wrinkle_detail(session, 1, std::nullopt, detail, "{}"));
    EXPECT_TRUE(store->wrinkle_details(session)->empty());
  }
  auto store = SessionStore::open(dir.path());
  ASSERT_TRUE(store);
  EXPECT_EQ(store->schema_version(), kSessionStoreSchemaVersion);
  EXPECT_EQ(store->orphans_removed(), 0);  // the failed call removed its first file itself
  WrinkleDetailData bad = detail;
  bad.displacement_mm.pop_back();
  EXPECT_FALSE(store->add_wrinkle_detail(session, 1, std::nullopt, bad, "{}"));
  bad = detail;
  bad.displacement_mm[2] = std::nanf("");
  EXPECT_FALSE(store->add_wrinkle_detail(session, 1, std::nullopt, bad, "{}"));
  auto id = store->add_wrinkle_detail(session, 1, std::nullopt, detail, R"({"regions": 2})");
  ASSERT_TRUE(id) << id.error().message;
  auto listed = store->wrinkle_details(session);
  ASSERT_TRUE(listed);
  ASSERT_EQ(listed->size(), 1u);
  EXPECT_EQ(listed->at(0).capture_index, 1);
  EXPECT_EQ(listed->at(0).width, 4);
  EXPECT_FALSE(listed->at(0).rig);
  EXPECT_EQ(listed->at(0).params_json, R"({"regions": 2})");
  auto read = store->read_wrinkle_detail(*id);
  ASSERT_TRUE(read) << read.error().message;
  EXPECT_EQ(read->displacement_mm, detail.displacement_mm);
  EXPECT_EQ(read->normal_png, detail.normal_png);
  EXPECT_FALSE(store->read_wrinkle_detail(*id + 100));
  auto report = store->verify();
  ASSERT_TRUE(report);
  EXPECT_TRUE(report->ok());
}

// Schema v7: a rig keeps which captures of its session have wrinkle detail (the booth's live map
// weights); a v6 store's rigs list none after the migration, and a v6 store refuses the list
// until a writer migrates it.
TEST(SessionStore, RigDetailCapturesRoundTripAndMigrate) {
  test::ScratchDir dir;
  RigData rig;
  rig.neutral = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  rig.triangles = {0, 1, 2};
  SubjectId subject = 0;
  SessionId session = 0;
  RigId old_rig = 0;
  RigData detailed = rig;
  detailed.detail_captures = {{2, "jaw_open"}, {1, "smile"}};
  {
    StoreOptions v6;
    v6.migrate_to = 6;
    auto store = SessionStore::open(dir.path(), v6);
    ASSERT_TRUE(store);
    subject = *store->add_subject("d");
    session = *store->create_session(subject, guide(3));
    old_rig = *store->add_rig(subject, session, rig);
    EXPECT_TRUE(store->read_rig(old_rig)->detail_captures.empty());
    auto refused = store->add_rig(subject, session, detailed);
    ASSERT_FALSE(refused);
    EXPECT_NE(refused.error().message.find("migrate"), std::string::npos);
  }
  auto store = SessionStore::open(dir.path());
  ASSERT_TRUE(store) << store.error().message;
  EXPECT_EQ(store->schema_version(), kSessionStoreSchemaVersion);
  EXPECT_TRUE(store->read_rig(old_rig)->detail_captures.empty());
  auto id = store->add_rig(subject, session, detailed);
  ASSERT_TRUE(id) << id.error().message;
  EXPECT_EQ(store->read_rig(*id)->detail_captures, detailed.detail_captures);
  auto serving = store->rig_for(session);
  ASSERT_TRUE(serving && *serving);
  EXPECT_EQ((*serving)->id, *id);
  EXPECT_EQ((*serving)->detail_captures, detailed.detail_captures);
  RigData twice = rig;
  twice.detail_captures = {{1, "smile"}, {1, "smile"}};
  EXPECT_FALSE(store->add_rig(subject, session, twice));
  twice.detail_captures = {{-1, "smile"}};
  EXPECT_FALSE(store->add_rig(subject, session, twice));
  auto report = store->verify();
  ASSERT_TRUE(report);
  EXPECT_TRUE(report->ok());
}

TEST(SessionStore, RigForPrefersTheSessionsOwnRig) {
  test::ScratchDir dir;
  auto store = SessionStore::open(dir.path());
  ASSERT_TRUE(store);
  const SubjectId subject = *store->add_subject("r");
  const SessionId first = *store->create_session(subject, guide(1));
  const SessionId second = *store->create_session(subject, guide(1));
  const SessionId third = *store->create_session(subject, guide(1));
  const SessionId other = *store->create_session(*store->add_subject("no rig"), guide(1));
  RigData rig;
  rig.neutral = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  rig.triangles = {0, 1, 2};
  EXPECT_FALSE(*store->rig_for(first));  // no rig yet
  const RigId from_first = *store->add_rig(subject, first, rig);
  const RigId from_first_newer = *store->add_rig(subject, first, rig);
  const RigId from_second = *store->add_rig(subject, second, rig);
  const RigId imported = *store->add_rig(subject, std::nullopt, rig);
  EXPECT_EQ((*store->rig_for(first))->id, from_first_newer);
  EXPECT_EQ((*store->rig_for(first))->session, first);
  EXPECT_EQ((*store->rig_for(second))->id, from_second);
  EXPECT_EQ((*store->rig_for(third))->id, imported);  // the subject's newest
  EXPECT_FALSE((*store->rig_for(third))->session);
  EXPECT_EQ((*store->newest_rig(subject))->id, imported);
  EXPECT_FALSE(*store->rig_for(other));
  EXPECT_FALSE(store->rig_for(999));  // no such session: an error, not "no rig"
  EXPECT_NE(from_first, from_first_newer);
}

TEST(SessionStore, OrphansAndTemporariesAreCleanedAtOpen) {
  test::ScratchDir dir;
  SessionId session = 0;
  fs::path folder;
  {
    auto store = SessionStore::open(dir.path());
    session = *store->create_session(*store->add_subject("f"), guide(2));
    ASSERT_TRUE(capture(*store, session, 0));
    folder = store->session(session)->folder;
  }
  std::ofstream(folder / "c1-a1-frames-deadbeef.fbseq") << "written, never committed";
  std::ofstream(folder / ".tmp-c1-a1-fused.fbdep-123") << "half";
  std::ofstream(dir.path() / "models" / ".tmp-bilinear.bin-9") << "half";
  auto store = SessionStore::open(dir.path());
  ASSERT_TRUE(store);
  EXPECT_EQ(store->orphans_removed(), 3);
  EXPECT_FALSE(fs::exists(folder / "c1-a1-frames-deadbeef.fbseq"));
  EXPECT_TRUE(store->read_capture(session, 0));
  EXPECT_TRUE(store->verify()->ok());
}

}  // namespace
}  // namespace fb
