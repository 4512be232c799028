// `facebooth model build --from-sessions` on a real store (issue 38, item 4): the streamed build
// (several passes over the rigs: --memory-mb holds two subjects) gives the same model as the
// in-memory one (--in-memory) with the same knobs, to float round-off.
#include <gtest/gtest.h>

#include <filesystem>
#include <random>

#include <nlohmann/json.hpp>

#include "algo/bilinear/bilinear_model.hpp"
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

// A subject's rig: a random identity, every fitting shape at its own amplitude.
RigData rig(const FaceModel& m, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> n(0, 1);
  std::uniform_real_distribution<float> amp(0.6f, 1.4f);
  std::vector<float> id(static_cast<std::size_t>(m.identity_count));
  for (auto& c : id) c = n(rng);
  RigData r;
  r.neutral.resize(static_cast<std::size_t>(m.vertex_count) * 3);
  m.evaluate(id, {}, r.neutral);
  for (int j = 0; j < m.fitting_expression_count; ++j) {
    const float a = amp(rng);
    const auto d = m.expression_shape(j);
    std::vector<float> s(r.neutral.size());
    for (std::size_t k = 0; k < s.size(); ++k) s[k] = r.neutral[k] + a * d[k];
    r.shapes.push_back(std::move(s));
    r.shape_names.push_back(m.expression_names[static_cast<std::size_t>(j)]);
  }
  r.triangles = m.triangles;
  return r;
}

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
      auto subject = store->add_subject("s" + std::to_string(i));
      ASSERT_TRUE(subject.ok());
      auto session = store->create_session(*subject, {"neutral"});
      ASSERT_TRUE(session.ok());
      ASSERT_TRUE(store->add_rig(*subject, *session, rig(*face, 40 + i)).ok());
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
