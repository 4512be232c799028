// `facebooth texture` end to end through the real binary: a stored session whose neutral take
// is a textured synthetic head turn (frames, 3D landmarks and the rendered skin as the fitted
// mesh, the unit calibration recorded), textured, scored against the renderer's painted skin,
// then exported and opened by outside readers (Khronos validator, assimp).
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "algo/texture/texel_map.hpp"
#include "drivers/camera/common/device_json.hpp"
#include "sim/camera/synthetic_camera.hpp"
#include "storage/asset_files.hpp"
#include "storage/export/png_file.hpp"
#include "storage/session_store.hpp"
#include "tests/common/gltf_validator.hpp"
#include "tests/common/run_command.hpp"

namespace fb {
namespace {

namespace fs = std::filesystem;

class TextureCli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("fb-texture-cli-" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(TextureCli, TexturesAStoredSessionAndExportsIt) {
  auto model = load_face_model();
  ASSERT_TRUE(model) << model.error().message;
  SyntheticOptions o;
  o.seed = 7;
  o.frame_count = 45;
  o.world.texture = true;
  auto camera = make_synthetic_camera(*model, o);
  ASSERT_TRUE(camera);
  ASSERT_TRUE((*camera)->start());
  const fs::path root = dir_ / "store";
  SessionId session = 0;
  {
    auto store = SessionStore::open(root);
    ASSERT_TRUE(store) << store.error().message;
    session = *store->create_session(*store->add_subject("textured"), {"neutral", "smile"});
    ASSERT_TRUE(
        store->set_session_calibration(session, to_device_json((*camera)->info().calibration)));
    ASSERT_TRUE(store->begin_capture(session, 0));
    CaptureInput input;
    for (int i = 0; i < o.frame_count; ++i) {
      RgbdFrame f;
      ASSERT_TRUE((*camera)->next_frame(f, std::chrono::milliseconds(1000)));
      if (i == 0) {
        for (const auto& p : (*camera)->truth()->landmarks_3d)
          input.landmarks.push_back({0.0f, 0.0f, true, static_cast<float>(p.x()),
                                     static_cast<float>(p.y()), static_cast<float>(p.z())});
        input.fused_depth = f.depth_mm;
      }
      input.frames.push_back(std::move(f));
    }
    ASSERT_TRUE(store->commit_capture(session, 0, input));
    MeshData mesh;
    for (int v = 0; v < model->vertex_count; ++v)
      for (int a = 0; a < 3; ++a) mesh.positions.push_back((*camera)->model_vertices()[v][a]);
    mesh.triangles = model->triangles;
    ASSERT_TRUE(store->add_mesh(session, 0, MeshRole::kNeutral, "neutral", mesh));
  }
  const fs::path png = dir_ / "atlas.png";
  auto r =
      test::run_command(std::string(FB_CLI_PATH) + " texture --size 512 --store " + root.string() +
                            " --session " + std::to_string(session) + " --png " + png.string(),
                        test::Stderr::kToLog);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  auto j = nlohmann::json::parse(r.out);
  std::cout << r.out << "\n";
  EXPECT_EQ(j["calibration"], "recorded");
  ASSERT_EQ(j["textures"].size(), 1u);
  EXPECT_EQ(j["textures"][0]["frames_aligned"], o.frame_count);
  EXPECT_GT(j["textures"][0]["observed_fraction"].get<double>(), 0.3);

  // The stored atlas against the painted skin over the well-seen face texels.
  std::ifstream in(png, std::ios::binary);
  std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)), {});
  auto atlas = decode_png(bytes);
  ASSERT_TRUE(atlas) << atlas.error().message;
  ASSERT_EQ(atlas->width, 1024);  // two UV tiles side by side
  ASSERT_EQ(atlas->height, 512);
  auto map = make_texel_map(model->atlas_uvs(), model->triangle_uvs, 1024, 512);
  ASSERT_TRUE(map);
  double se = 0.0, n = 0.0;
  Eigen::Vector3d xy = Eigen::Vector3d::Zero(), xx = Eigen::Vector3d::Zero();
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> pairs;
  for (int y = 200; y < 480; y += 3)  // the UV layout's face: the lower middle of tile 1
    for (int x = 65; x < 190; x += 2) {
      const auto i = map->index(x, y);
      const auto t = map->triangle[i];
      if (t < 0) continue;
      bool face = true;
      for (int k = 0; k < 3; ++k)
        face = face &&
               model->triangles[3 * t + k] < static_cast<std::uint32_t>(model->face_vertex_count);
      if (!face) continue;
      const Eigen::Vector3d want =
          255.0 * (*camera)->surface_albedo(t, map->bary[i][1], map->bary[i][2]).cast<double>();
      const Rgb8 c = atlas->at(x, y);
      const Eigen::Vector3d got(c.r, c.g, c.b);
      pairs.emplace_back(got, want);
      xy += got.cwiseProduct(want);
      xx += got.cwiseProduct(got);
    }
  ASSERT_GT(pairs.size(), 1000u);
  const Eigen::Vector3d gain = xy.cwiseQuotient(xx);
  for (const auto& [got, want] : pairs) {
    se += (got.cwiseProduct(gain) - want).squaredNorm() / 3.0;
    n += 1.0;
  }
  const double psnr = 10.0 * std::log10(255.0 * 255.0 / (se / n));
  std::printf("stored texture vs painted skin: PSNR %.1f dB over %zu face texels\n", psnr,
              pairs.size());
  EXPECT_GT(psnr, 26.0);

  // Exports take the stored texture: glTF baseColorTexture (validator: hasTextures, one UV
  // set, no errors or warnings), OBJ + MTL + PNG (assimp), FaceWarehouse's per-pose texture.
  const std::string base = std::string(FB_CLI_PATH) + " export --store " + root.string() +
                           " --session " + std::to_string(session);
  ASSERT_EQ(test::run_command(base + " --format glb --out " + (dir_ / "glb").string(),
                              test::Stderr::kToLog)
                .exit_code,
            0);
  ASSERT_EQ(test::run_command(base + " --format obj --out " + (dir_ / "obj").string(),
                              test::Stderr::kToLog)
                .exit_code,
            0);
  EXPECT_TRUE(fs::exists(dir_ / "obj" / "face.png"));
  std::string skip;
  fs::path glb;
  for (const auto& e : fs::directory_iterator(dir_ / "glb"))
    if (e.path().extension() == ".glb") glb = e.path();
  auto report = test::validate_gltf(glb, skip);
  if (report) {
    EXPECT_EQ((*report)["numErrors"], 0) << (*report)["messages"].dump(1);
    EXPECT_EQ((*report)["numWarnings"], 0) << (*report)["messages"].dump(1);
    EXPECT_EQ((*report)["info"]["hasTextures"], true);
    EXPECT_EQ((*report)["info"]["maxUVs"], 1);
  }
  const std::string assimp = FB_ASSIMP_PATH;
  if (!assimp.empty()) {
    auto info = test::run_command(assimp + " info " + (dir_ / "obj" / "neutral.obj").string(),
                                  test::Stderr::kMerged);
    ASSERT_EQ(info.exit_code, 0) << info.out;
    EXPECT_NE(info.out.find("face.png"), std::string::npos) << info.out;
  }
  if (!report) GTEST_SKIP() << skip;
  if (assimp.empty()) GTEST_SKIP() << "assimp (assimp-utils) is not installed";
}

TEST_F(TextureCli, ASessionWithoutAFittedNeutralIsAClearError) {
  const fs::path root = dir_ / "store";
  {
    auto store = SessionStore::open(root);
    ASSERT_TRUE(store);
    ASSERT_TRUE(store->create_session(*store->add_subject("x"), {"neutral"}));
  }
  auto r = test::run_command(
      std::string(FB_CLI_PATH) + " texture --store " + root.string() + " --session 1",
      test::Stderr::kMerged);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("no fitted neutral"), std::string::npos) << r.out;
  r = test::run_command(std::string(FB_CLI_PATH) + " texture --store " + root.string(),
                        test::Stderr::kMerged);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("--session"), std::string::npos) << r.out;
}

}  // namespace
}  // namespace fb
