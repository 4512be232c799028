// Takes through the real facebooth binary: `facebooth track --store` records a take in the session
// store, `facebooth export --take` writes it as Live Link Face CSV, and the CSV matches what the
// tracker streamed (the live `--csv` written from the tracker's outputs in the same run) and
// what the store holds. Also `--rig-from-store`: a subject with a stored rig is tracked without
// calibration; a subject without one falls back to calibrating.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "algo/tracking/arkit.hpp"
#include "sim/camera/synthetic_camera.hpp"
#include "storage/asset_files.hpp"
#include "storage/export/livelink_csv.hpp"
#include "storage/export/synthetic_subject.hpp"
#include "storage/session_store.hpp"
#include "tests/common/run_command.hpp"

namespace fb {
namespace {

namespace fs = std::filesystem;

// stdout only; stderr goes to the test log.
test::CommandRun facebooth(const std::string& args) {
  return test::run_command(std::string(FB_CLI_PATH) + " " + args, test::Stderr::kToLog);
}

// facebooth-lab track: the same command, with --landmarks truth (the lab's ground truth).
test::CommandRun facebooth_lab(const std::string& args) {
  return test::run_command(std::string(FB_LAB_PATH) + " " + args, test::Stderr::kToLog);
}

class TrackStoreCli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("fb-track-store-" +
            std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()) + "-" +
            std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(TrackStoreCli, TrackStoreExportMatchesTheTrackedValues) {
  const fs::path store_dir = dir_ / "store";
  const fs::path live_csv = dir_ / "live.csv";
  constexpr int kFrames = 45;
  auto r = facebooth_lab("track --camera synthetic:frames=45,seed=3 --landmarks truth --store " +
                         store_dir.string() + " --csv " + live_csv.string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const auto j = nlohmann::json::parse(r.out);
  ASSERT_TRUE(j["take"].is_number_integer()) << r.out;
  const TakeId take = j["take"].get<TakeId>();
  EXPECT_EQ(j["frames"], kFrames);
  EXPECT_GE(j["frames_with_face"].get<int>(), kFrames - 2) << r.out;

  // The stored take: pose, the 52 ARKit curves by name, and the frame times in their own
  // column (TakeData::times_s), not disguised as a shape.
  {
    StoreOptions ro;
    ro.read_only = true;
    auto store = SessionStore::open(store_dir, ro);
    ASSERT_TRUE(store.ok()) << store.error().message;
    auto stored = store->read_take(take);
    ASSERT_TRUE(stored.ok()) << stored.error().message;
    const TakeInfo& info = stored->info;
    EXPECT_EQ(info.subject, j["subject"].get<SubjectId>());
    EXPECT_FALSE(info.session);  // no session named, no stored rig
    ASSERT_EQ(info.frame_count, kFrames);
    ASSERT_EQ(info.shape_names.size(), static_cast<std::size_t>(kArkitShapeCount));
    EXPECT_EQ(info.shape_names[0], "eyeBlinkLeft");
    EXPECT_NEAR(info.fps, 30.0, 1e-9);
    ASSERT_EQ(stored->times_s.size(), static_cast<std::size_t>(kFrames));
    for (int f = 0; f < kFrames; ++f) {
      EXPECT_NEAR(stored->times_s[static_cast<std::size_t>(f)], f / 30.0, 1e-3) << "frame " << f;
      // A unit quaternion and a face ~0.7 m in front of the camera.
      const float* v = stored->frame(f).data();
      EXPECT_NEAR(std::sqrt(v[3] * v[3] + v[4] * v[4] + v[5] * v[5] + v[6] * v[6]), 1.0, 1e-4);
      EXPECT_GT(v[2], 500.0f);
      EXPECT_LT(v[2], 900.0f);
    }
  }

  // Export and compare with the live CSV of the same run, curve by curve and frame by frame.
  const fs::path out = dir_ / "export";
  r = facebooth("export --take " + std::to_string(take) + " --store " + store_dir.string() +
                " --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const fs::path exported = out / ("take_" + std::to_string(take) + ".csv");
  ASSERT_TRUE(fs::exists(exported));
  auto rows = read_livelink_csv(exported, 30.0);
  ASSERT_TRUE(rows.ok()) << rows.error().message;
  auto live = read_livelink_csv(live_csv, 30.0);
  ASSERT_TRUE(live.ok()) << live.error().message;
  ASSERT_EQ(rows->size(), static_cast<std::size_t>(kFrames));
  ASSERT_EQ(live->size(), rows->size());
  double max_weight_diff = 0, max_angle_diff = 0, weight_sum = 0;
  for (std::size_t f = 0; f < rows->size(); ++f) {
    const LiveLinkRow& a = (*rows)[f];
    const LiveLinkRow& b = (*live)[f];
    EXPECT_NEAR(a.time_s - (*rows)[0].time_s, b.time_s - (*live)[0].time_s, 2e-3) << f;
    for (int k = 0; k < kArkitShapeCount; ++k) {
      max_weight_diff = std::max(max_weight_diff, std::abs(double(a.weights[k]) - b.weights[k]));
      weight_sum += a.weights[k];
    }
    max_angle_diff =
        std::max({max_angle_diff, std::abs(a.head.yaw - b.head.yaw),
                  std::abs(a.head.pitch - b.head.pitch), std::abs(a.head.roll - b.head.roll)});
  }
  // 6 decimals in the CSV; the pose goes through float in the store.
  EXPECT_LT(max_weight_diff, 2e-6);
  EXPECT_LT(max_angle_diff, 1e-5);
  // Not a take of zeros: the synthetic head turns (motion=headturn) and the curves are written.
  double yaw_range = 0;
  for (const auto& row : *rows) yaw_range = std::max(yaw_range, std::abs(row.head.yaw));
  EXPECT_GT(yaw_range, 5.0 * M_PI / 180.0);
}

TEST_F(TrackStoreCli, StoredRigSkipsCalibrationAndMissingRigFallsBack) {
  auto model = load_face_model(fs::path(FB_DATA_DIR) / "facemodel.fbfm");
  ASSERT_TRUE(model.ok()) << model.error().message;
  const fs::path store_dir = dir_ / "store";
  SubjectId with_rig = 0, without_rig = 0;
  {
    auto store = SessionStore::open(store_dir);
    ASSERT_TRUE(store.ok()) << store.error().message;
    // The mean face's rig (identity 0) matches the camera's identity=neutral subject.
    SyntheticSubjectOptions o;
    o.identity_sigma = 0.0f;
    o.pose_count = 2;
    auto subject = make_synthetic_subject(*model, o);
    ASSERT_TRUE(subject.ok()) << subject.error().message;
    auto added = store->add_subject("rigged");
    ASSERT_TRUE(added.ok());
    with_rig = *added;
    ASSERT_TRUE(store->add_rig(with_rig, std::nullopt, subject->rig).ok());
    auto other = store->add_subject("no rig yet");
    ASSERT_TRUE(other.ok());
    without_rig = *other;
  }
  const std::string camera = "--camera synthetic:frames=25,identity=neutral,seed=4 ";
  auto r = facebooth("track " + camera + "--store " + store_dir.string() + " --subject " +
                     std::to_string(with_rig) + " --rig-from-store");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  auto j = nlohmann::json::parse(r.out);
  EXPECT_NE(j["subject_model"].get<std::string>().find("stored rig"), std::string::npos) << r.out;
  EXPECT_FALSE(j["states"].contains("calibrating")) << r.out;
  EXPECT_GE(j["frames_with_face"].get<int>(), 24) << r.out;
  EXPECT_EQ(j["subject"].get<SubjectId>(), with_rig);

  r = facebooth("track " + camera + "--store " + store_dir.string() + " --subject " +
                std::to_string(without_rig) + " --rig-from-store");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  j = nlohmann::json::parse(r.out);
  EXPECT_NE(j["subject_model"].get<std::string>().find("no stored rig"), std::string::npos)
      << r.out;
  EXPECT_GT(j["states"].value("calibrating", 0), 0) << r.out;
  EXPECT_EQ(j["subject"].get<SubjectId>(), without_rig);

  // Bad input is a clear error, not a crash.
  r = facebooth("track " + camera + "--store " + store_dir.string() + " --subject 999");
  EXPECT_NE(r.exit_code, 0);
  r = facebooth("track " + camera + "--rig-from-store");
  EXPECT_NE(r.exit_code, 0);

  // Both subjects' takes are in the store.
  StoreOptions ro;
  ro.read_only = true;
  auto store = SessionStore::open(store_dir, ro);
  ASSERT_TRUE(store.ok());
  EXPECT_EQ(store->takes(with_rig)->size(), 1u);
  EXPECT_EQ(store->takes(without_rig)->size(), 1u);
}

// Issue 37: a take tracked with a session's stored rig records that session, whether the
// command names the subject (the rig says which session built it) or the session itself (the
// rig serving it, SessionStore::rig_for). A take without a session stays without one.
TEST_F(TrackStoreCli, TakeTrackedWithASessionsRigRecordsTheSession) {
  auto model = load_face_model(fs::path(FB_DATA_DIR) / "facemodel.fbfm");
  ASSERT_TRUE(model.ok()) << model.error().message;
  const fs::path store_dir = dir_ / "store";
  SubjectId subject = 0;
  SessionId session = 0;
  {
    auto store = SessionStore::open(store_dir);
    ASSERT_TRUE(store.ok()) << store.error().message;
    SyntheticSubjectOptions o;
    o.identity_sigma = 0.0f;
    o.pose_count = 2;
    auto synthetic = make_synthetic_subject(*model, o);
    ASSERT_TRUE(synthetic.ok()) << synthetic.error().message;
    subject = *store->add_subject("rigged in a session");
    session = *store->create_session(subject, {"neutral"});
    ASSERT_TRUE(store->add_rig(subject, session, synthetic->rig).ok());
  }
  const std::string camera =
      "--camera synthetic:frames=12,identity=neutral,seed=4 --store " + store_dir.string() + " ";
  std::vector<TakeId> takes;
  for (const std::string who :
       {"--subject " + std::to_string(subject), "--session " + std::to_string(session)}) {
    auto r = facebooth("track " + camera + who + " --rig-from-store");
    ASSERT_EQ(r.exit_code, 0) << who << "\n" << r.out;
    const auto j = nlohmann::json::parse(r.out);
    EXPECT_NE(j["subject_model"].get<std::string>().find("stored rig"), std::string::npos) << r.out;
    EXPECT_EQ(j["subject"].get<SubjectId>(), subject) << r.out;
    EXPECT_EQ(j["session"].get<SessionId>(), session) << r.out;
    takes.push_back(j["take"].get<TakeId>());
  }
  StoreOptions ro;
  ro.read_only = true;
  auto store = SessionStore::open(store_dir, ro);
  ASSERT_TRUE(store.ok());
  for (TakeId id : takes) {
    auto take = store->read_take(id);
    ASSERT_TRUE(take.ok()) << take.error().message;
    EXPECT_EQ(take->info.session, session) << "take " << id;
    EXPECT_EQ(take->info.subject, subject) << "take " << id;
  }
  // Giving both is refused with a clear message (a session names its subject).
  auto r = facebooth("track " + camera + "--session " + std::to_string(session) + " --subject " +
                     std::to_string(subject));
  EXPECT_NE(r.exit_code, 0);
}

// --save-rig: the subject the tracker calibrated is stored as their rig (the fitted neutral and
// the 53 blendshapes), which --rig-from-store then tracks with, without calibrating. With a
// bilinear model the blendshapes are the subject's own from it instead of the generic ones.
TEST_F(TrackStoreCli, SaveRigStoresTheCalibratedSubject) {
  auto model = load_face_model(fs::path(FB_DATA_DIR) / "facemodel.fbfm");
  ASSERT_TRUE(model.ok()) << model.error().message;
  const std::string store = "--store " + (dir_ / "store").string();
  auto r = facebooth("track --camera synthetic:frames=30,seed=5 --save-rig " + store);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  auto j = nlohmann::json::parse(r.out);
  ASSERT_TRUE(j["rig"].is_number_integer()) << r.out;
  const SubjectId subject = j["subject"].get<SubjectId>();
  const std::string rigged = " --subject " + std::to_string(subject);

  // The stored neutral is this subject's: against the synthetic camera's true rest-pose face
  // it is far closer than the mean face is.
  auto options = parse_synthetic_options("seed=5", *model);
  ASSERT_TRUE(options.ok()) << options.error().message;
  auto camera = make_synthetic_camera(*model, *options);
  ASSERT_TRUE(camera.ok()) << camera.error().message;
  const auto truth = (*camera)->model_vertices();
  auto rms_to_truth = [&](std::span<const float> mesh) {
    double sum = 0;
    for (int v = 0; v < model->face_vertex_count; ++v)
      sum +=
          (Eigen::Vector3f(mesh[3 * v], mesh[3 * v + 1], mesh[3 * v + 2]) - truth[v]).squaredNorm();
    return std::sqrt(sum / model->face_vertex_count);
  };
  const int jaw = model->expression_index("jawOpen");
  auto delta_from_generic = [&](const RigData& rig) {  // max |rig delta - model delta|, jawOpen
    const auto generic = model->expression_shape(jaw);
    const auto& shape = rig.shapes[static_cast<std::size_t>(jaw)];
    double worst = 0;
    for (std::size_t c = 0; c < shape.size(); ++c)
      worst = std::max(worst, std::abs(double(shape[c]) - rig.neutral[c] - generic[c]));
    return worst;
  };
  StoreOptions ro;
  ro.read_only = true;
  {
    auto opened = SessionStore::open(dir_ / "store", ro);
    ASSERT_TRUE(opened.ok());
    auto rig = opened->read_rig(j["rig"].get<RigId>());
    ASSERT_TRUE(rig.ok()) << rig.error().message;
    ASSERT_EQ(rig->shape_count(), model->fitting_expression_count);
    EXPECT_EQ(rig->shape_names[static_cast<std::size_t>(jaw)], "jawOpen");
    const double fitted = rms_to_truth(rig->neutral), mean = rms_to_truth(model->neutral);
    std::printf("stored neutral vs the true face: %.2f mm rms (mean face %.2f mm)\n", fitted, mean);
    EXPECT_LT(fitted, 0.5 * mean);
    EXPECT_LT(delta_from_generic(*rig), 1e-3);  // the face model's generic blendshapes
  }

  r = facebooth("track --camera synthetic:frames=20,seed=5 --rig-from-store " + store + rigged);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  j = nlohmann::json::parse(r.out);
  EXPECT_NE(j["subject_model"].get<std::string>().find("stored rig"), std::string::npos) << r.out;
  EXPECT_FALSE(j["states"].contains("calibrating")) << r.out;
  EXPECT_GE(j["frames_with_face"].get<int>(), 19) << r.out;

  // With a bilinear model: the subject's own blendshapes, C x2 w x3 (u_e - u_0). A model built
  // from the face model gives every identity nearly the generic deltas, so they differ only by
  // what its knobs truncate (0.10 mm here), against < 0.001 mm for the generic copy above.
  const std::string bilinear = (dir_ / "tracking.fbbm").string();
  ASSERT_EQ(facebooth("model build --from-face-model --identities 40 --id-knobs 20 "
                      "--exp-knobs 54 --out " +
                      bilinear)
                .exit_code,
            0);
  r = facebooth("track --camera synthetic:frames=20,seed=5 --save-rig --model " + bilinear + " " +
                store + rigged);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  j = nlohmann::json::parse(r.out);
  {
    auto opened = SessionStore::open(dir_ / "store", ro);
    ASSERT_TRUE(opened.ok());
    auto rigs = opened->rigs(subject);
    ASSERT_TRUE(rigs.ok());
    ASSERT_EQ(rigs->size(), 2u);
    EXPECT_EQ(rigs->front().id, j["rig"].get<RigId>());  // newest first
    auto rig = opened->read_rig(j["rig"].get<RigId>());
    ASSERT_TRUE(rig.ok()) << rig.error().message;
    const double own = delta_from_generic(*rig);
    std::printf("bilinear rig: jawOpen differs from the generic one by up to %.2f mm\n", own);
    EXPECT_GT(own, 0.02);
  }

  // What cannot work is refused before anything is tracked.
  EXPECT_NE(facebooth("track --camera synthetic:frames=5 --save-rig").exit_code, 0);
  EXPECT_NE(
      facebooth("track --camera synthetic:frames=5 --save-rig --rig-from-store " + store + rigged)
          .exit_code,
      0);
}

}  // namespace
}  // namespace fb

namespace fb {
namespace {

// The demo's take (scripts/demo step 5): the head turns while the face opens the jaw, smiles,
// blinks and raises the brows (synthetic anim=expressive), so its Live Link CSV shows curves;
// the Timecode is the time of day at which the take was tracked.
TEST_F(TrackStoreCli, ExpressiveTakeCsvShowsItsCurves) {
  const fs::path csv = dir_ / "take.csv";
  const double before = local_time_of_day_s(std::chrono::system_clock::now());
  auto r = facebooth(
      "track --camera synthetic:seed=1,motion=headturn,anim=expressive,frames=150 --frames 150 "
      "--csv " +
      csv.string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  auto rows = read_livelink_csv(csv, 30.0);
  ASSERT_TRUE(rows.ok()) << rows.error().message;
  ASSERT_EQ(rows->size(), 150u);
  // The first row's time of day is when tracking started (allow a midnight wrap).
  double start = (*rows)[0].time_s - before;
  if (start < -43200) start += 86400;
  EXPECT_GE(start, -1.0);
  EXPECT_LT(start, 120.0);
  EXPECT_NEAR((*rows)[149].time_s - (*rows)[0].time_s, 149 / 30.0, 1e-3);
  struct Curve {
    const char* name;
    float truth_peak;
  } const curves[] = {{"JawOpen", 0.6f},         {"MouthSmileLeft", 0.8f},
                      {"MouthSmileRight", 0.8f}, {"EyeBlinkLeft", 1.0f},
                      {"EyeBlinkRight", 1.0f},   {"BrowInnerUp", 0.8f},
                      {"BrowOuterUpLeft", 0.8f}, {"BrowOuterUpRight", 0.8f}};
  for (const auto& curve : curves) {
    const auto it = std::find(kLiveLinkNames.begin(), kLiveLinkNames.end(), curve.name);
    ASSERT_NE(it, kLiveLinkNames.end());
    const auto k = static_cast<std::size_t>(it - kLiveLinkNames.begin());
    float peak = 0.0f, first_frames = 0.0f;
    for (std::size_t f = 0; f < rows->size(); ++f) {
      peak = std::max(peak, (*rows)[f].weights[k]);
      if (f < 10) first_frames = std::max(first_frames, (*rows)[f].weights[k]);
    }
    std::printf("%s: peak %.3f (script %.1f), first 10 frames <= %.3f\n", curve.name, peak,
                curve.truth_peak, first_frames);
    EXPECT_GT(peak, 0.6f * curve.truth_peak) << curve.name;
    EXPECT_LT(first_frames, 0.1f) << curve.name;  // the take starts neutral
  }
}

}  // namespace
}  // namespace fb
