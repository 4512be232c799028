// The storage commands end to end through the real facebooth binary: export from the face
// model and from a stored session, import, store info, and the eval storage output contract.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "storage/asset_files.hpp"
#include "storage/export/export_folder.hpp"
#include "storage/export/synthetic_subject.hpp"
#include "storage/session_store.hpp"
#include "storage/take_writer.hpp"
#include "tests/common/run_command.hpp"

namespace fb {
namespace {

namespace fs = std::filesystem;

// stdout only; stderr goes to the test log.
test::CommandRun facebooth(const std::string& args) {
  return test::run_command(std::string(FB_CLI_PATH) + " " + args, test::Stderr::kToLog);
}

test::CommandRun facebooth_lab(const std::string& args) {
  return test::run_command(std::string(FB_LAB_PATH) + " " + args, test::Stderr::kToLog);
}

class StorageCli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("fb-cli-storage-" +
            std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()) + "-" +
            std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(StorageCli, ExportFromFaceModelThenImport) {
  const fs::path out = dir_ / "fw";
  auto r = facebooth("export --from-face-model --seed 2 --format facewarehouse --tester 7 --out " +
                     out.string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["format"], "facewarehouse");
  EXPECT_EQ(j["poses"], 20);
  EXPECT_TRUE(fs::exists(out / "Tester_7" / "Blendshape" / "shape.bs"));
  EXPECT_TRUE(verify_export_folder(out));
  // The same destination again is refused (usage stays intact), --force replaces it.
  EXPECT_EQ(facebooth("export --from-face-model --format obj --out " + out.string()).exit_code, 1);
  EXPECT_EQ(
      facebooth("export --from-face-model --format obj --force --out " + out.string()).exit_code,
      0);
  EXPECT_TRUE(fs::exists(out / "neutral.obj"));
  EXPECT_EQ(facebooth("export --format glb --out " + (dir_ / "x").string()).exit_code, 2);

  ASSERT_EQ(
      facebooth("export --from-face-model --seed 2 --format fw --out " + (dir_ / "fw2").string())
          .exit_code,
      0);
  const fs::path store = dir_ / "store";
  r = facebooth("import --in " + (dir_ / "fw2").string() + " --save --store " + store.string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  j = nlohmann::json::parse(r.out);
  ASSERT_EQ(j["testers"].size(), 1u);
  EXPECT_EQ(j["testers"][0]["poses"], 20);
  EXPECT_EQ(j["testers"][0]["vertices"], 11248);
  // What was imported exports again from the store.
  r = facebooth("export --session " + std::to_string(j["testers"][0]["session"].get<int>()) +
                " --store " + store.string() + " --format ply --out " + (dir_ / "ply").string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_TRUE(fs::exists(dir_ / "ply" / "poses" / "pose_19.ply"));
}

TEST_F(StorageCli, ExportAStoredSessionWhileTheWriterIsOpen) {
  const fs::path root = dir_ / "store";
  auto model = load_face_model();
  ASSERT_TRUE(model);
  auto subject = make_synthetic_subject(*model, {});
  ASSERT_TRUE(subject);
  auto writer = SessionStore::open(root);  // stays open: exports read through their own connection
  ASSERT_TRUE(writer);
  auto session = store_synthetic_subject(*writer, *subject, "cli");
  ASSERT_TRUE(session) << session.error().message;
  auto r = facebooth("export --session " + std::to_string(*session) + " --store " + root.string() +
                     " --format facewarehouse --out " + (dir_ / "fw").string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_TRUE(fs::exists(dir_ / "fw" / "Tester_1" / "TrainingPose" / "pose_19.png"));
  r = facebooth("store info --verify --store " + root.string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["verify"]["ok"], true);
  EXPECT_EQ(j["sessions"][0]["done"], 20);
  EXPECT_EQ(facebooth("export --session 99 --store " + root.string() + " --out " +
                      (dir_ / "none").string())
                .exit_code,
            1);
}

TEST_F(StorageCli, ExportTakeAsLiveLinkCsvAndModelFile) {
  const fs::path root = dir_ / "store";
  TakeId take = 0;
  ModelId model = 0;
  {
    auto store = SessionStore::open(root);
    ASSERT_TRUE(store);
    TakeWriter writer({"jawOpen", "eyeBlinkLeft", "notArkit"}, 30.0);
    RigidPose pose;
    pose.translation = Eigen::Vector3d(0, 0, 600);
    for (int f = 0; f < 3; ++f) {
      const std::vector<float> weights = {0.25f * f, 0.5f, 0.9f};
      ASSERT_TRUE(writer.add_frame(f / 30.0, pose, weights));
    }
    take = *writer.store(*store, *store->add_subject("t"), std::nullopt);
    const std::vector<std::uint8_t> bytes(1000, 7);
    model = *store->add_model("bilinear", R"({"identities":2})", bytes);
  }
  auto r = facebooth("export --take " + std::to_string(take) + " --store " + root.string() +
                     " --out " + (dir_ / "take").string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  std::ifstream csv(dir_ / "take" / ("take_" + std::to_string(take) + ".csv"));
  std::string header, row;
  std::getline(csv, header);
  EXPECT_EQ(header.rfind("Timecode,BlendShapeCount,", 0), 0u) << header;
  int rows = 0;
  std::string last;
  while (std::getline(csv, row)) ++rows, last = row;
  EXPECT_EQ(rows, 3);
  EXPECT_NE(last.find("0.500000"), std::string::npos) << last;  // jawOpen of frame 2
  EXPECT_TRUE(verify_export_folder(dir_ / "take"));
  r = facebooth("export --model " + std::to_string(model) + " --store " + root.string() +
                " --out " + (dir_ / "model").string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_EQ(fs::file_size(dir_ / "model" / "bilinear.bin"), 1000u);
  EXPECT_EQ(facebooth("export --take 1 --model 1 --out " + (dir_ / "x").string()).exit_code, 2);
}

TEST_F(StorageCli, EvalStorageRefusesAScratchFolderItCannotCreate) {
  const auto r = test::run_command(
      std::string(FB_LAB_PATH) + " eval storage --json --trials 0 --scratch /dev/null/x",
      test::Stderr::kMerged);
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_NE(r.out.find("cannot create the scratch folder /dev/null/x/facebooth-eval-storage-"),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("writable folder"), std::string::npos) << r.out;
}

TEST_F(StorageCli, EvalStorageFollowsTheOutputContract) {
  auto r =
      facebooth_lab("eval storage --json --trials 4 --commits 2 --frames-per-capture 2 --scratch " +
                    dir_.string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  auto j = nlohmann::json::parse(r.out);
  for (const char* key :
       {"crash_trials", "crash_trials_survived", "capture_commit_ms", "export_s"}) {
    EXPECT_TRUE(j.contains(key)) << key;
  }
  EXPECT_EQ(j["crash_trials"], 4);
  EXPECT_EQ(j["crash_trials_survived"], 4);
  EXPECT_GT(j["capture_commit_ms"].get<double>(), 0.0);
  EXPECT_GT(j["export_s"].get<double>(), 0.0);
  EXPECT_EQ(j["facewarehouse_import_exact"], true);
  EXPECT_GT(j["exports"]["glb"]["bytes"].get<double>(), 1e6);
  // The scratch store is removed afterwards.
  EXPECT_TRUE(fs::is_empty(dir_));
}

}  // namespace
}  // namespace fb
