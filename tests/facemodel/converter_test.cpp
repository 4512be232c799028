// facebooth-convert-facemodel end to end: clear errors for bad sources, and the committed
// asset is exactly what the converter produces from ../shared today.
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>

#include "tests/facemodel/test_util.hpp"

namespace fb {
namespace {

namespace fs = std::filesystem;

struct RunResult {
  int exit_code = -1;
  std::string output;  // stderr and stdout
};

RunResult run_converter(const std::string& args, const fs::path& log) {
  const std::string cmd =
      std::string("\"") + FB_CONVERTER_PATH + "\" " + args + " > \"" + log.string() + "\" 2>&1";
  const int status = std::system(cmd.c_str());
  RunResult r;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  std::ifstream in(log);
  std::ostringstream ss;
  ss << in.rdbuf();
  r.output = ss.str();
  return r;
}

class facemodel_converter : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("fb_convert_test_" +
            std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(dir_);
    fs::create_directories(dir_ / "src" / "FaceXModel");
  }
  void TearDown() override { fs::remove_all(dir_); }
  void write(const fs::path& rel, const std::string& text) {
    std::ofstream(dir_ / "src" / rel, std::ios::binary) << text;
  }
  void write_valid_json() {
    write("FaceXModel/vertex_indices.json",
          R"({"expressions": ["jawOpen"], "idx_to_landmark_verts": [0]})");
    write("jawline_indices.json", R"({"right_jawline_for_lmk_0_7": [1]})");
  }
  RunResult convert() {
    return run_converter("--source \"" + (dir_ / "src").string() + "\" --out \"" +
                             (dir_ / "out.fbfm").string() + "\"",
                         dir_ / "log.txt");
  }
  fs::path dir_;
};

TEST_F(facemodel_converter, MissingSourceDirectory) {
  const auto r = run_converter("--source /nonexistent/ict --out " + (dir_ / "o.fbfm").string(),
                               dir_ / "log.txt");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("/nonexistent/ict does not exist"), std::string::npos) << r.output;
}

TEST_F(facemodel_converter, MissingFilesAreListed) {
  write("FaceXModel/generic_neutral_mesh.obj", "v 0 0 0\n");
  const auto r = convert();
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("missing: vertex_indices.json jawline_indices.json"), std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(dir_ / "out.fbfm"));
}

TEST_F(facemodel_converter, GarbledJson) {
  write("FaceXModel/generic_neutral_mesh.obj", "v 0 0 0\n");
  write("FaceXModel/vertex_indices.json", "{\"expressions\": [");
  write("jawline_indices.json", "{}");
  const auto r = convert();
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("vertex_indices.json is not valid JSON"), std::string::npos) << r.output;
}

TEST_F(facemodel_converter, GarbledObjLineIsNamed) {
  write_valid_json();
  write("FaceXModel/generic_neutral_mesh.obj", "# header\nv 0 0 0\nv 1.0 2.0 abc\n");
  const auto r = convert();
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("generic_neutral_mesh.obj:3: cannot read coordinate 3"),
            std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(dir_ / "out.fbfm"));
}

TEST_F(facemodel_converter, TruncatedObjIsReported) {
  write_valid_json();
  write("FaceXModel/generic_neutral_mesh.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  const auto r = convert();
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("has 3 vertices, expected 26719"), std::string::npos) << r.output;
}

TEST_F(facemodel_converter, CommittedAssetIsUpToDate) {
  const fs::path src = test::source_dir();
  if (src.empty()) GTEST_SKIP() << "ICT FaceKit source not found under " FB_SHARED_DIR;
  const auto r = run_converter(
      "--source \"" + src.string() + "\" --out \"" + (dir_ / "fresh.fbfm").string() + "\"",
      dir_ / "log.txt");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("wrote"), std::string::npos) << r.output;
  std::ifstream in(dir_ / "fresh.fbfm", std::ios::binary);
  const std::string fresh((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto& committed = test::asset_bytes();
  ASSERT_EQ(fresh.size(), committed.size())
      << "data/facemodel.fbfm is stale: re-run facebooth-convert-facemodel and commit it";
  EXPECT_EQ(std::memcmp(fresh.data(), committed.data(), fresh.size()), 0)
      << "data/facemodel.fbfm is stale: re-run facebooth-convert-facemodel and commit it";
}

}  // namespace
}  // namespace fb
