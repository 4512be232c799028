// `facebooth track --drive`: a live track (the synthetic camera playing sim/camera's expressive
// take) driving subject B's stored rig, each frame's mesh read back and compared with B's own
// truth for the recipe the camera played (sim/subject/retarget_case.hpp).
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <iostream>

#include <nlohmann/json.hpp>

#include "sim/subject/retarget_case.hpp"
#include "storage/export/mesh_files.hpp"
#include "tests/common/run_command.hpp"
#include "tests/common/test_face_model.hpp"

namespace fb {
namespace {

namespace fs = std::filesystem;

TEST(TrackDrive, LiveTrackDrivesAnotherSubjectsRig) {
  const fs::path dir =
      fs::temp_directory_path() / ("facebooth-track-drive-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  constexpr int kFrames = 90;
  auto c = make_retarget_case(dir / "store", test::face_model(), kFrames);
  ASSERT_TRUE(c) << c.error().message;
  auto run = test::run_command(
      std::string(FB_CLI_PATH) + " track --camera synthetic:seed=1,motion=static,anim=expressive," +
          "frames=" + std::to_string(kFrames) + " --frames " + std::to_string(kFrames) +
          " --store " + (dir / "store").string() + " --drive subject:" + std::to_string(c->target) +
          " --drive-out " + (dir / "driven").string(),
      test::Stderr::kDropped);
  ASSERT_EQ(run.exit_code, 0) << run.out;
  const auto report = nlohmann::json::parse(run.out);
  EXPECT_EQ(report["drive"]["frames"].get<int>(), kFrames);
  // After the identity calibration (10 frames) the tracked weights drive B: mean distance to
  // B's truth over the vertices the truth moves >= 0.1 mm.
  double sum = 0;
  long long n = 0;
  for (int f = 20; f < kFrames; ++f) {
    char name[32];
    std::snprintf(name, sizeof name, "frame_%06d.obj", f);
    auto mesh = read_obj(dir / "driven" / name);
    ASSERT_TRUE(mesh) << mesh.error().message;
    const std::vector<float> truth = retarget_truth(*c, test::face_model(), f);
    const auto& got = mesh->mesh.positions;
    ASSERT_EQ(got.size(), truth.size());
    for (std::size_t v = 0; v < truth.size() / 3; ++v) {
      double moved = 0, err = 0;
      for (int k = 0; k < 3; ++k) {
        const double d = truth[3 * v + k] - c->target_rig.neutral[3 * v + k];
        const double e = got[3 * v + k] - truth[3 * v + k];
        moved += d * d, err += e * e;
      }
      if (moved < 0.01) continue;
      sum += std::sqrt(err);
      ++n;
    }
  }
  ASSERT_GT(n, 0);
  std::cout << "live drive: " << sum / n << " mm over " << n << " moving vertex samples\n";
  EXPECT_LT(sum / n, 1.0);  // mm
  // What is wrong is said: an existing --drive-out, a subject without a rig, no --store.
  const std::string track = std::string(FB_CLI_PATH) + " track --camera synthetic:frames=5 ";
  const std::string store = " --store " + (dir / "store").string();
  auto exists = test::run_command(track + store + " --drive subject:" + std::to_string(c->target) +
                                      " --drive-out " + (dir / "driven").string(),
                                  test::Stderr::kMerged);
  EXPECT_EQ(exists.exit_code, 1);
  EXPECT_NE(exists.out.find("already exists"), std::string::npos) << exists.out;
  auto no_rig =
      test::run_command(track + store + " --drive subject:999 --drive-out " + (dir / "d2").string(),
                        test::Stderr::kMerged);
  EXPECT_EQ(no_rig.exit_code, 1) << no_rig.out;
  auto no_store = test::run_command(
      track + "--drive subject:2 --drive-out " + (dir / "d3").string(), test::Stderr::kMerged);
  EXPECT_EQ(no_store.exit_code, 1);
  EXPECT_NE(no_store.out.find("--drive needs --store"), std::string::npos) << no_store.out;
  fs::remove_all(dir);
}

}  // namespace
}  // namespace fb
