// `facebooth model build --from-sessions` on a real store (issue 38, item 4): the streamed build
// (several passes over the rigs: --memory-mb holds two subjects) gives the same model as the
// in-memory one (--in-memory) with the same knobs, to float round-off.
#include <gtest/gtest.h>

#include <filesystem>
#include <random>

#include <nlohmann/json.hpp>

#include "algo/bilinear/bilinear_model.hpp"
#include "sim/subject/synthetic_rigs.hpp"
#include "storage/asset_files.hpp"
#include "storage/durable_file.hpp"
#include "storage/session_store.hpp"
#include "tests/common/run_command.hpp"

namespace fb {
namespace {

namespace fs = std::filesystem;

struct TempDir {
  fs::path path;
  TempDir() {
    path = fs::temp_directory_path() / ("fb-model-build-" + std::to_string(std::random_device{}()));
    fs::create_directories(path);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

BilinearModel read_model(const fs::path& p) {
  auto bytes = read_file_bytes(p);
  EXPECT_TRUE(bytes.ok());
  auto m = parse_bilinear_model(std::as_bytes(std::span(*bytes)));
  EXPECT_TRUE(m.ok()) << (m.ok() ? "" : m.error().message);
  return std::move(*m);
}

TEST(ModelBuildCli, StreamedFromTheStoreEqualsTheInMemoryBuild) {
  auto face = load_face_model();
  ASSERT_TRUE(face.ok());
  TempDir dir;
  const int subjects = 7;
  {
    auto store = SessionStore::open(dir.path / "store");
    ASSERT_TRUE(store.ok());
    for (int i = 0; i < subjects; ++i) {
      ASSERT_TRUE(add_synthetic_rig_subject(*store, *face, "s" + std::to_string(i), 40 + i).ok());
    }
  }
  auto build = [&](const std::string& name, const std::string& extra) {
    const std::string cmd = std::string(FB_CLI_PATH) + " model build --from-sessions --store " +
                            (dir.path / "store").string() + " --id-knobs 5 --exp-knobs 12 --out " +
                            (dir.path / name).string() + extra;
    auto run = test::run_command(cmd, test::Stderr::kToLog);
    EXPECT_EQ(run.exit_code, 0) << run.out;
    auto j = nlohmann::json::parse(run.out, nullptr, false);
    EXPECT_FALSE(j.is_discarded()) << run.out;
    return j;
  };
  // 16 MB holds two subjects (7.3 MB each): 4 passes over the store for the Gram matrices.
  const auto streamed = build("streamed.fbbm", " --memory-mb 16");
  const auto dense = build("dense.fbbm", " --in-memory");
  EXPECT_EQ(streamed["gram_passes"], 4);
  EXPECT_EQ(streamed["rig_reads"], 2 + 4 + 6 + 7 + 7);  // each pass its panel and before; core
  EXPECT_EQ(streamed["identities"], subjects);
  const BilinearModel a = read_model(dir.path / "streamed.fbbm");
  const BilinearModel b = read_model(dir.path / "dense.fbbm");
  ASSERT_EQ(a.id_knobs, 5);
  ASSERT_EQ(a.exp_knobs, 12);
  ASSERT_EQ(a.identity_count, b.identity_count);
  for (std::size_t k = 0; k < a.identity_spectrum.size(); ++k)
    EXPECT_NEAR(a.identity_spectrum[k], b.identity_spectrum[k], 1e-5 * b.identity_spectrum[0]);
  // Every training subject in every expression, as each model reconstructs it.
  std::vector<float> va(static_cast<std::size_t>(a.coordinate_count())), vb(va.size());
  double worst = 0, scale = 0;
  for (int i = 0; i < a.identity_count; ++i)
    for (int e = 0; e < a.expression_count; ++e) {
      a.evaluate(a.identity_row(i), a.expression_row(e), va);
      b.evaluate(b.identity_row(i), b.expression_row(e), vb);
      for (std::size_t k = 0; k < va.size(); ++k) {
        worst = std::max(worst, static_cast<double>(std::abs(va[k] - vb[k])));
        scale = std::max(scale, static_cast<double>(std::abs(vb[k])));
      }
    }
  std::printf("streamed vs in-memory: max difference %.3g mm (faces up to %.0f mm)\n", worst,
              scale);
  EXPECT_LT(worst, 1e-5 * scale);
}

}  // namespace
}  // namespace fb
