// `facebooth transfer` end to end: the real binary on OBJ folders written by `facebooth export`
// and on a real SQLite session store, scored against the synthetic subjects' known truth.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iostream>

#include <nlohmann/json.hpp>

#include "sim/subject/remesh.hpp"
#include "storage/export/mesh_files.hpp"
#include "storage/export/synthetic_subject.hpp"
#include "tests/common/run_command.hpp"
#include "tests/common/test_face_model.hpp"

namespace fb {
namespace {

namespace fs = std::filesystem;

test::CommandRun facebooth(const std::string& args, test::Stderr err = test::Stderr::kMerged) {
  return test::run_command(std::string(FB_CLI_PATH) + " " + args, err);
}

class TransferCli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("facebooth-transfer-" + std::to_string(::getpid()) + "-" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  fs::path dir_;
};

SyntheticSubject subject(std::uint64_t seed) {
  SyntheticSubjectOptions o;
  o.seed = seed;
  auto s = make_synthetic_subject(test::face_model(), o);
  EXPECT_TRUE(s) << s.error().message;
  return std::move(*s);
}

// Mean distance to `truth` over the vertices that move >= 0.1 mm from `neutral` in the truth.
double moving_error_mm(const std::vector<float>& out, const std::vector<float>& truth,
                       const std::vector<float>& neutral) {
  double sum = 0;
  int n = 0;
  for (std::size_t v = 0; v + 2 < truth.size(); v += 3) {
    double motion = 0, err = 0;
    for (int d = 0; d < 3; ++d) {
      motion += std::pow(double{truth[v + d]} - neutral[v + d], 2);
      err += std::pow(double{out[v + d]} - truth[v + d], 2);
    }
    if (std::sqrt(motion) < 0.1) continue;
    sum += std::sqrt(err);
    ++n;
  }
  return n > 0 ? sum / n : -1.0;  // -1: the shape moves no skin vertex
}

TEST_F(TransferCli, ExportedSubjectOntoAnotherNeutralMatchesItsTruth) {
  ASSERT_EQ(
      facebooth("export --from-face-model --seed 1 --format obj --out " + path("src")).exit_code,
      0);
  ASSERT_EQ(
      facebooth("export --from-face-model --seed 2 --format obj --out " + path("dst")).exit_code,
      0);
  auto run = facebooth("transfer --from " + path("src") + " --to " + path("dst/neutral.obj") +
                           " --out " + path("out") + " --format obj",
                       test::Stderr::kDropped);
  ASSERT_EQ(run.exit_code, 0) << run.out;
  const auto report = nlohmann::json::parse(run.out);
  const SyntheticSubject truth = subject(2);
  EXPECT_EQ(report["expressions"].get<int>(), truth.rig.shape_count());
  EXPECT_GT(report["factor_ms"].get<double>(), 0.0);
  // Pooled over every shape, as eval transfer's cross_subject_vertex_error_mm (budget 0.5).
  double sum = 0;
  int shapes = 0;
  for (int j = 0; j < truth.rig.shape_count(); ++j) {
    const std::string& name = truth.rig.shape_names[static_cast<std::size_t>(j)];
    char index[16];
    std::snprintf(index, sizeof index, "%02d", j + 1);  // export numbers from 01
    auto mesh = read_obj(dir_ / "out" / "blendshapes" / (std::string(index) + "_" + name + ".obj"));
    ASSERT_TRUE(mesh) << mesh.error().message;
    const double e = moving_error_mm(
        mesh->mesh.positions, truth.rig.shapes[static_cast<std::size_t>(j)], truth.rig.neutral);
    if (e < 0) continue;  // PupilDilate_L/R move no skin vertex
    EXPECT_LT(e, 1.5) << name;
    sum += e;
    ++shapes;
  }
  EXPECT_LT(sum / shapes, 0.5);
}

// Section V from the command line: subject 2 decimated (another topology, written as OBJ) with
// its 68 landmark points in a file; the source on the face model's mesh uses the model's own.
TEST_F(TransferCli, AnotherTopologyWithLandmarksMatchesItsTruth) {
  const FaceModel& m = test::face_model();
  ASSERT_EQ(
      facebooth("export --from-face-model --seed 1 --format obj --out " + path("src")).exit_code,
      0);
  const SyntheticSubject truth = subject(2);
  const std::vector<std::uint32_t> keep(m.landmark_vertices.begin(), m.landmark_vertices.end());
  const Remesh r = decimate(m.triangles, points_from_floats(m.neutral), 0.5, keep);
  const Points neutral = points_from_floats(truth.rig.neutral);
  {
    std::ofstream obj(path("target.obj"));
    obj << encode_obj({floats_from_points(r.apply(neutral)), r.triangles});
    std::ofstream marks(path("target.landmarks"));
    marks << "# the 68 iBUG points of subject 2, mm\n";
    for (std::uint32_t v : m.landmark_vertices)
      marks << neutral(v, 0) << " " << neutral(v, 1) << " " << neutral(v, 2) << "\n";
  }
  auto run = facebooth("transfer --from " + path("src") + " --to " + path("target.obj") +
                           " --to-landmarks " + path("target.landmarks") + " --out " + path("out"),
                       test::Stderr::kDropped);
  ASSERT_EQ(run.exit_code, 0) << run.out;
  const auto report = nlohmann::json::parse(run.out);
  EXPECT_GT(report["correspondence_ms"].get<double>(), 0.0);
  EXPECT_LT(report["unmatched_vertices"].get<int>(), 10);
  double sum = 0;
  int shapes = 0;
  for (int j = 0; j < truth.rig.shape_count(); ++j) {
    const std::string& name = truth.rig.shape_names[static_cast<std::size_t>(j)];
    char index[16];
    std::snprintf(index, sizeof index, "%02d", j + 1);
    auto mesh = read_obj(dir_ / "out" / "blendshapes" / (std::string(index) + "_" + name + ".obj"));
    ASSERT_TRUE(mesh) << mesh.error().message;
    const Points shape = points_from_floats(truth.rig.shapes[static_cast<std::size_t>(j)]);
    const double e = moving_error_mm(mesh->mesh.positions, floats_from_points(r.apply(shape)),
                                     floats_from_points(r.apply(neutral)));
    if (e < 0) continue;
    sum += e;
    ++shapes;
  }
  EXPECT_LT(sum / shapes, 1.0);  // mm, eval transfer's cross_topology budget
  // Without the file: dlib's points on frontal renders of both faces (measured 0.74 mm).
  auto found = facebooth("transfer --from " + path("src") + " --to " + path("target.obj") +
                             " --out " + path("out-found"),
                         test::Stderr::kDropped);
  ASSERT_EQ(found.exit_code, 0) << found.out;
  EXPECT_EQ(nlohmann::json::parse(found.out)["feature_points"], "dlib on frontal renders");
  sum = 0;
  shapes = 0;
  for (int j = 0; j < truth.rig.shape_count(); ++j) {
    const std::string& name = truth.rig.shape_names[static_cast<std::size_t>(j)];
    char index[16];
    std::snprintf(index, sizeof index, "%02d", j + 1);
    auto mesh =
        read_obj(dir_ / "out-found" / "blendshapes" / (std::string(index) + "_" + name + ".obj"));
    ASSERT_TRUE(mesh) << mesh.error().message;
    const Points shape = points_from_floats(truth.rig.shapes[static_cast<std::size_t>(j)]);
    const double e = moving_error_mm(mesh->mesh.positions, floats_from_points(r.apply(shape)),
                                     floats_from_points(r.apply(neutral)));
    if (e < 0) continue;
    sum += e;
    ++shapes;
  }
  std::cout << "found feature points: " << sum / shapes << " mm\n";
  EXPECT_LT(sum / shapes, 1.0);
}

TEST_F(TransferCli, StoredSessionOntoStoredSessionWritesEveryFormat) {
  {
    auto store = SessionStore::open(path("store"));
    ASSERT_TRUE(store) << store.error().message;
    ASSERT_TRUE(store_synthetic_subject(*store, subject(3), "a"));
    ASSERT_TRUE(store_synthetic_subject(*store, subject(4), "b"));
  }
  for (const char* format : {"glb", "facewarehouse", "ply"}) {
    auto run =
        facebooth("transfer --store " + path("store") + " --from session:1 --to session:2 --out " +
                  path(std::string("out-") + format) + " --format " + format);
    EXPECT_EQ(run.exit_code, 0) << format << ": " << run.out;
    EXPECT_TRUE(fs::exists(dir_ / (std::string("out-") + format) / "manifest.json")) << format;
  }
}

TEST_F(TransferCli, BadInputIsRefusedWithWhatToDo) {
  ASSERT_EQ(
      facebooth("export --from-face-model --seed 1 --format obj --out " + path("src")).exit_code,
      0);
  {
    std::ofstream tri(path("tri.obj"));
    tri << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  }
  auto other = facebooth("transfer --from " + path("src") + " --to " + path("tri.obj") + " --out " +
                         path("o1"));
  EXPECT_EQ(other.exit_code, 1);
  EXPECT_NE(other.out.find("does not have the source's topology"), std::string::npos) << other.out;
  EXPECT_NE(other.out.find("--to-landmarks"), std::string::npos) << other.out;
  auto missing = facebooth("transfer --from " + path("nowhere") + " --to " + path("tri.obj") +
                           " --out " + path("o2"));
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_NE(missing.out.find("is not a folder"), std::string::npos) << missing.out;
  auto no_store =
      facebooth("transfer --from session:1 --to " + path("tri.obj") + " --out " + path("o3"));
  EXPECT_EQ(no_store.exit_code, 1);
  EXPECT_NE(no_store.out.find("needs --store"), std::string::npos) << no_store.out;
  auto bad_id =
      facebooth("transfer --from session:x --to " + path("tri.obj") + " --out " + path("o4"));
  EXPECT_NE(bad_id.out.find("session:ID"), std::string::npos) << bad_id.out;
  EXPECT_FALSE(fs::exists(dir_ / "o1"));
  auto exists = facebooth("transfer --from " + path("src") + " --to " + path("src/neutral.obj") +
                          " --out " + path("src"));
  EXPECT_EQ(exists.exit_code, 1);
  EXPECT_NE(exists.out.find("--force"), std::string::npos) << exists.out;
  EXPECT_EQ(exists.out.find("transfer: "), std::string::npos) << "refused before the work";
  auto help = facebooth("transfer --help");
  EXPECT_EQ(help.exit_code, 0);
  EXPECT_NE(help.out.find("session:ID"), std::string::npos);
  EXPECT_NE(help.out.find("dlib finds the 68"), std::string::npos);
}

}  // namespace
}  // namespace fb
