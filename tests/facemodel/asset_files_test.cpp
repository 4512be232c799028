// storage/asset_files: where the asset is looked for and how failures read.
#include "storage/asset_files.hpp"

#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>
#include <string>

#include "tests/facemodel/test_util.hpp"

namespace fb {
namespace {

namespace fs = std::filesystem;

// Sets or clears $FACEBOOTH_DATA_DIR for one scope and restores the previous value.
class ScopedDataDirEnv {
 public:
  explicit ScopedDataDirEnv(const char* value) {
    if (const char* old = std::getenv("FACEBOOTH_DATA_DIR")) old_ = old;
    if (value) {
      setenv("FACEBOOTH_DATA_DIR", value, 1);
    } else {
      unsetenv("FACEBOOTH_DATA_DIR");
    }
  }
  ~ScopedDataDirEnv() {
    if (old_) {
      setenv("FACEBOOTH_DATA_DIR", old_->c_str(), 1);
    } else {
      unsetenv("FACEBOOTH_DATA_DIR");
    }
  }

 private:
  std::optional<std::string> old_;
};

fs::path temp_dir() {
  fs::path d =
      fs::temp_directory_path() /
      ("fb_facemodel_test_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) +
       "_" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
  fs::create_directories(d);
  return d;
}

TEST(facemodel_asset_files, EnvironmentVariableWins) {
  ScopedDataDirEnv env("/some/where");
  EXPECT_EQ(data_directory(), fs::path("/some/where"));
  EXPECT_EQ(default_face_model_path(), fs::path("/some/where/facemodel.fbfm"));
}

TEST(facemodel_asset_files, FallsBackToTheSourceTree) {
  ScopedDataDirEnv env(nullptr);
  if (fs::exists("/usr/share/facebooth/facemodel.fbfm")) {
    EXPECT_EQ(data_directory(), fs::path("/usr/share/facebooth"));
  } else {
    EXPECT_EQ(data_directory(), fs::path(FB_DATA_DIR));
  }
}

TEST(facemodel_asset_files, DefaultLoadFindsTheCommittedAsset) {
  ScopedDataDirEnv env(nullptr);
  auto m = load_face_model();
  ASSERT_TRUE(m.ok()) << m.error().message;
  EXPECT_EQ(m->vertex_count, 11248);
  EXPECT_NE(m->provenance.find("MIT"), std::string::npos);
}

TEST(facemodel_asset_files, MissingFileSaysWhereItLookedAndWhatToRun) {
  ScopedDataDirEnv env("/nonexistent/facebooth-data");
  auto m = load_face_model();
  ASSERT_FALSE(m.ok());
  const std::string& msg = m.error().message;
  EXPECT_NE(msg.find("/nonexistent/facebooth-data/facemodel.fbfm"), std::string::npos) << msg;
  EXPECT_NE(msg.find("FACEBOOTH_DATA_DIR"), std::string::npos) << msg;
  EXPECT_NE(msg.find("facebooth-convert-facemodel"), std::string::npos) << msg;
}

TEST(facemodel_asset_files, DamagedFileNamesThePathAndTheProblem) {
  const fs::path dir = temp_dir();
  const fs::path file = dir / "facemodel.fbfm";
  {
    const auto& bytes = test::asset_bytes();
    ASSERT_GT(bytes.size(), 1000u);
    std::ofstream out(file, std::ios::binary);
    out.write(reinterpret_cast<const char*>(bytes.data()), 1000);
  }
  auto m = load_face_model(file);
  ASSERT_FALSE(m.ok());
  EXPECT_NE(m.error().message.find(file.string()), std::string::npos) << m.error().message;
  EXPECT_NE(m.error().message.find("truncated at byte 1000"), std::string::npos)
      << m.error().message;

  auto d = load_face_model(dir);
  ASSERT_FALSE(d.ok());
  EXPECT_NE(d.error().message.find("not a regular file"), std::string::npos) << d.error().message;
  fs::remove_all(dir);
}

}  // namespace
}  // namespace fb
