// `facebooth retarget` end to end: a real session store with synthetic subjects A and B
// (sim/subject/retarget_case.hpp), A's stored take driving B's rig, the written OBJ poses read
// back and compared with B's own truth for the same recipe; and its errors.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>

#include <nlohmann/json.hpp>

#include "sim/subject/retarget_case.hpp"
#include "storage/export/mesh_files.hpp"
#include "tests/common/run_command.hpp"
#include "tests/common/test_face_model.hpp"

namespace fb {
namespace {

namespace fs = std::filesystem;

class RetargetCli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("facebooth-retarget-" + std::to_string(::getpid()) + "-" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    auto c = make_retarget_case(dir_ / "store", test::face_model(), 60);
    ASSERT_TRUE(c) << c.error().message;
    case_ = std::move(*c);
  }
  void TearDown() override { fs::remove_all(dir_); }
  test::CommandRun facebooth(const std::string& args) {
    return test::run_command(
        std::string(FB_CLI_PATH) + " retarget --store " + (dir_ / "store").string() + " " + args,
        test::Stderr::kMerged);
  }
  fs::path dir_;
  RetargetCase case_;
};

TEST_F(RetargetCli, TakeOfADrivesTheRigOfBAsBsOwnTruth) {
  const std::string out = (dir_ / "out").string();
  auto run = facebooth("--take " + std::to_string(case_.take) + " --to subject:" +
                       std::to_string(case_.target) + " --every 10 --out " + out);
  ASSERT_EQ(run.exit_code, 0) << run.out;
  const auto json = nlohmann::json::parse(run.out.substr(run.out.find('{')));
  EXPECT_EQ(json["frames"].get<int>(), 6);
  EXPECT_EQ(json["shapes_driven"].get<int>(), 53);
  double worst = 0, motion = 0;
  for (int i = 0; i < 6; ++i) {
    auto mesh = read_obj(fs::path(out) / "poses" / ("pose_" + std::to_string(i) + ".obj"));
    ASSERT_TRUE(mesh) << mesh.error().message;
    const auto truth = retarget_truth(case_, test::face_model(), 10 * i);
    ASSERT_EQ(mesh->mesh.positions.size(), truth.size());
    for (std::size_t v = 0; v + 2 < truth.size(); v += 3) {
      double e = 0, m = 0;
      for (std::size_t d = 0; d < 3; ++d) {
        e += std::pow(double{mesh->mesh.positions[v + d]} - truth[v + d], 2);
        m += std::pow(double{truth[v + d]} - case_.target_rig.neutral[v + d], 2);
      }
      worst = std::max(worst, std::sqrt(e));
      motion = std::max(motion, std::sqrt(m));
    }
  }
  EXPECT_LT(worst, 0.01);  // mm: the OBJ's printed precision
  EXPECT_GT(motion, 3.0);  // the frames do move (jaw, smile)
}

TEST_F(RetargetCli, SaysWhatIsWrong) {
  const std::string take = "--take " + std::to_string(case_.take);
  auto no_rig = facebooth(take + " --to subject:99 --out " + (dir_ / "a").string());
  EXPECT_NE(no_rig.exit_code, 0);
  EXPECT_NE(no_rig.out.find("subject 99 has no rig"), std::string::npos) << no_rig.out;
  auto bad_to = facebooth(take + " --to somebody --out " + (dir_ / "b").string());
  EXPECT_NE(bad_to.exit_code, 0);
  EXPECT_NE(bad_to.out.find("session:ID or subject:ID"), std::string::npos) << bad_to.out;
  auto glb = facebooth(take + " --to subject:" + std::to_string(case_.target) +
                       " --format glb --out " + (dir_ / "c").string());
  EXPECT_NE(glb.exit_code, 0);
  EXPECT_NE(glb.out.find("no animation"), std::string::npos) << glb.out;
  auto no_take = facebooth("--take 999 --to subject:" + std::to_string(case_.target) + " --out " +
                           (dir_ / "d").string());
  EXPECT_NE(no_take.exit_code, 0);
  EXPECT_FALSE(fs::exists(dir_ / "d"));
}

}  // namespace
}  // namespace fb
