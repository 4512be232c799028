// `facebooth export --take` writes take_ID.glb (issue 40 item 5, "applied in the exported
// animation"), through the real binary on a store built here: a session with the generic rig
// on the face model's neutral, wrinkle detail on the neutral, the brow raiser and the smile
// (known relief in the forehead and at the eye corners), and a 60-frame take with a moving
// head. The .glb is read back and checked against the store, computed independently of the
// exporter: the animated mesh at a frame (base + sum_k w_k delta_k from the accessors) is the
// rig blended by the model shapes the take's curves give, at each glTF vertex's place in the
// face model's UV layout, plus the blended detail E = N + sum_e c_e (D_e - N) (c from the
// guide recipes' pseudo-inverse in closed form) along the neutral's normals; the animation's
// input is the take's times, its weights the take's curves, its head pose the take's pose in the
// scene frame. The Khronos validator and assimp read the file.
#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Dense>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "algo/core/mesh_normals.hpp"
#include "algo/guide/guide_expressions.hpp"
#include "algo/texture/texel_map.hpp"
#include "algo/tracking/arkit.hpp"
#include "algo/wrinkles/detail_mesh.hpp"
#include "storage/asset_files.hpp"
#include "storage/export/png_file.hpp"
#include "storage/session_store.hpp"
#include "storage/take_writer.hpp"
#include "tests/common/gltf_validator.hpp"
#include "tests/common/run_command.hpp"
#include "tests/common/uv_locator.hpp"
#include "tests/export/glb_reader.hpp"

namespace fb {
namespace {

namespace fs = std::filesystem;

constexpr int kMapWidth = 512, kMapHeight = 256, kFrames = 60;
const std::vector<std::string> kCaptures = {"neutral", "brow_raiser", "smile"};

float bump(const Eigen::Vector3f& p, const Eigen::Vector3f& centre, float radius) {
  const float r = (p - centre).norm();
  return r < radius ? 0.5f * (1.0f + std::cos(float(M_PI) * r / radius)) : 0.0f;
}

// Known relief per capture (mm), in the layout: fine lines on the neutral's forehead, deep
// forehead lines on the brow raiser, crow's feet at both eye corners on the smile.
std::vector<std::vector<float>> relief(const FaceModel& model, const TexelMap& map) {
  auto landmark = [&](int l) {
    const std::uint32_t v = model.landmark_vertices[static_cast<std::size_t>(l)];
    return Eigen::Vector3f(model.neutral[3 * v], model.neutral[3 * v + 1],
                           model.neutral[3 * v + 2]);
  };
  const Eigen::Vector3f forehead = 0.5f * (landmark(19) + landmark(24)) + Eigen::Vector3f(0, 22, 0);
  const Eigen::Vector3f corner_a = landmark(36) + Eigen::Vector3f(-8, 0, 0);
  const Eigen::Vector3f corner_b = landmark(45) + Eigen::Vector3f(8, 0, 0);
  std::vector<std::vector<float>> maps(3, std::vector<float>(map.triangle.size(), 0.0f));
  for (std::size_t t = 0; t < map.triangle.size(); ++t) {
    if (map.triangle[t] < 0) continue;
    const Eigen::Vector3f p = texel_point(map, t, model.triangles, model.neutral);
    const float lines = std::sin(2.0f * float(M_PI) * p.y() / 5.0f);
    const float n = 0.05f * lines * bump(p, forehead, 28.0f);
    const float feet = std::sin(2.0f * float(M_PI) * (p.x() + 0.5f * p.y()) / 4.0f) *
                       (bump(p, corner_a, 14.0f) + bump(p, corner_b, 14.0f));
    maps[0][t] = n;
    maps[1][t] = n + 0.6f * lines * bump(p, forehead, 28.0f);
    maps[2][t] = n + 0.4f * feet;
  }
  return maps;
}

// The take's frames: curves and head pose that move (smile, brows, jaw, blinks; a head turn).
struct TakeFrames {
  std::vector<double> times;
  std::vector<std::array<float, kArkitShapeCount>> curves;
  std::vector<RigidPose> poses;
};
TakeFrames take_frames() {
  TakeFrames t;
  const Eigen::Quaterniond facing(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()));
  auto index = [](std::string_view name) {
    return std::find(kArkitNames.begin(), kArkitNames.end(), name) - kArkitNames.begin();
  };
  for (int f = 0; f < kFrames; ++f) {
    const double s = f / double(kFrames - 1);
    t.times.push_back(100.0 + f / 30.0 + 0.003 * std::sin(1.7 * f));  // measured, not f / fps
    std::array<float, kArkitShapeCount> c{};
    for (int k = 0; k < kArkitShapeCount; ++k) c[k] = 0.04f * float((k * 7 + f) % 5);
    c[index("browInnerUp")] = c[index("browOuterUpLeft")] = c[index("browOuterUpRight")] =
        float(std::sin(M_PI * s));
    c[index("mouthSmileLeft")] = c[index("mouthSmileRight")] = float(s);
    c[index("jawOpen")] = float(0.5 * (1 - std::cos(4 * M_PI * s)));
    c[index("eyeBlinkLeft")] = f % 20 < 3 ? 1.0f : 0.0f;
    t.curves.push_back(c);
    RigidPose pose;
    pose.rotation = facing *
                    Eigen::AngleAxisd(0.4 * std::sin(2 * M_PI * s), Eigen::Vector3d::UnitY()) *
                    Eigen::AngleAxisd(0.15 * s, Eigen::Vector3d::UnitX());
    pose.translation = Eigen::Vector3d(15 * std::sin(2 * M_PI * s), -20 + 5 * s, 680 + 20 * s);
    t.poses.push_back(pose);
  }
  return t;
}

class TakeGltf : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    auto model = load_face_model();
    ASSERT_TRUE(model) << model.error().message;
    model_ = std::make_unique<FaceModel>(std::move(*model));
  }
  static void TearDownTestSuite() { model_.reset(); }
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("fb-take-gltf-" +
            std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()) + "-" +
            std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    uvs_ = model_->atlas_uvs();
    auto map = make_texel_map(uvs_, model_->triangle_uvs, kMapWidth, kMapHeight);
    ASSERT_TRUE(map) << map.error().message;
    map_ = std::move(*map);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // The generic rig on the face model's neutral: its 53 fitting shapes.
  RigData rig() const {
    RigData r;
    r.neutral = model_->neutral;
    r.triangles = model_->triangles;
    for (int j = 0; j < model_->fitting_expression_count; ++j) {
      std::vector<float> shape = r.neutral;
      const auto e = model_->expression_shape(j);
      for (std::size_t i = 0; i < shape.size(); ++i) shape[i] += e[i];
      r.shapes.push_back(std::move(shape));
      r.shape_names.push_back(model_->expression_names[static_cast<std::size_t>(j)]);
    }
    return r;
  }

  // A store with one take; the take records its session when `session`, whose subject has a
  // rig when `with_rig` and whose captures have wrinkle detail when `with_detail`.
  TakeId make_store(bool session, bool with_rig, bool with_detail) {
    auto store = SessionStore::open(dir_ / "store");
    EXPECT_TRUE(store) << store.error().message;
    const SubjectId subject = *store->add_subject("animated");
    const SessionId id = *store->create_session(subject, kCaptures);
    std::optional<RigId> rig_id;
    if (with_rig) rig_id = *store->add_rig(subject, id, rig());
    if (with_detail) {
      maps_ = relief(*model_, map_);
      ColorImage flat;
      flat.resize(kMapWidth, kMapHeight);
      for (auto& p : flat.pixels) p = {128, 128, 255};
      for (int i = 0; i < 3; ++i) {
        WrinkleDetailData d{kMapWidth, kMapHeight, maps_[static_cast<std::size_t>(i)],
                            *encode_png(flat)};
        EXPECT_TRUE(store->add_wrinkle_detail(id, i, rig_id, d, "{}"));
      }
    }
    std::vector<std::string> names(kArkitNames.begin(), kArkitNames.end());
    TakeWriter writer(names, 30.0);
    for (int f = 0; f < kFrames; ++f)
      EXPECT_TRUE(writer.add_frame(frames_.times[f], frames_.poses[f], frames_.curves[f]));
    auto take = writer.store(*store, subject,
                             session ? std::optional<SessionId>(id) : std::optional<SessionId>());
    EXPECT_TRUE(take) << take.error().message;
    return take ? *take : 0;
  }

  // `export --take`: its JSON summary; the wall time goes to `seconds`.
  nlohmann::json export_take(TakeId take, const fs::path& out, double* seconds = nullptr) {
    const auto start = std::chrono::steady_clock::now();
    auto r = test::run_command(std::string(FB_CLI_PATH) + " export --store " +
                                   (dir_ / "store").string() + " --take " + std::to_string(take) +
                                   " --out " + out.string(),
                               test::Stderr::kToLog);
    if (seconds != nullptr)
      *seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    EXPECT_EQ(r.exit_code, 0) << r.out;
    auto j = nlohmann::json::parse(r.out, nullptr, false);
    EXPECT_FALSE(j.is_discarded()) << r.out;
    return j;
  }

  // Map weights c = P^T a, P = pinv(W) = W^T (W W^T)^-1, W the two captures' guide recipes.
  std::vector<double> map_weights(const std::vector<float>& a) const {
    auto guide = load_guide_expressions(*model_);
    EXPECT_TRUE(guide);
    Eigen::MatrixXd w(2, model_->fitting_expression_count);
    for (int e = 0; e < 2; ++e) {
      auto recipe = guide_weights(guide->expressions[static_cast<std::size_t>(
                                      guide->find(kCaptures[static_cast<std::size_t>(e) + 1]))],
                                  *model_);
      EXPECT_TRUE(recipe);
      recipe->resize(static_cast<std::size_t>(model_->fitting_expression_count));
      for (int s = 0; s < model_->fitting_expression_count; ++s) w(e, s) = (*recipe)[s];
    }
    const Eigen::VectorXd av = Eigen::Map<const Eigen::VectorXf>(a.data(), a.size()).cast<double>();
    const Eigen::VectorXd c = (w * w.transpose()).ldlt().solve(w * av);
    return {c[0], c[1]};
  }

  static std::unique_ptr<FaceModel> model_;
  fs::path dir_;
  std::vector<float> uvs_;
  TexelMap map_;
  std::vector<std::vector<float>> maps_;
  TakeFrames frames_ = take_frames();
};
std::unique_ptr<FaceModel> TakeGltf::model_;

// The glTF mesh at frame f from the accessors: base + sum_k w_k(f) delta_k, in mm.
std::vector<double> animated_mesh(const test::Glb& glb, const std::vector<float>& weights, int f) {
  const auto& primitive = glb.json["meshes"][0]["primitives"][0];
  const auto base = glb.floats(primitive["attributes"]["POSITION"].get<int>());
  std::vector<double> out(base.begin(), base.end());
  const auto& targets = primitive["targets"];
  for (std::size_t k = 0; k < targets.size(); ++k) {
    const double w = weights[static_cast<std::size_t>(f) * targets.size() + k];
    if (w == 0.0) continue;
    const auto delta = glb.floats(targets[k]["POSITION"].get<int>());
    for (std::size_t i = 0; i < out.size(); ++i) out[i] += w * delta[i];
  }
  for (double& x : out) x *= 1000.0;
  return out;
}

// The mesh the store says frame f should show, at every glTF vertex (mm): the rig blended by
// the model weights of the take's curves, at the vertex's place on the surface (its UV), plus
// the blended detail (when `maps` has the three captures') along the neutral's normals. The
// height of a vertex is the mean over its seam copies, as one surface point has one position.
struct Expected {
  std::vector<double> positions;
  double max_height = 0.0;
  int unlocated = 0;
};
Expected expected_mesh(const FaceModel& model, const std::vector<float>& layout,
                       const TexelMap& texels, const test::Glb& glb,
                       const std::array<float, kArkitShapeCount>& curves,
                       const std::vector<std::vector<float>>& maps, const std::vector<double>& c) {
  auto mapping = make_arkit_mapping(model);
  EXPECT_TRUE(mapping);
  std::vector<float> a(static_cast<std::size_t>(model.fitting_expression_count), 0.0f);
  mapping->to_model(curves, a);
  std::vector<double> rig(model.neutral.begin(), model.neutral.end());
  for (int s = 0; s < model.fitting_expression_count; ++s) {
    const auto e = model.expression_shape(s);
    for (std::size_t i = 0; i < rig.size(); ++i) rig[i] += a[s] * double{e[i]};
  }
  const std::vector<float> normals = vertex_normals(model.neutral, model.triangles);
  FloatImage detail;
  if (!maps.empty()) {
    detail.resize(kMapWidth, kMapHeight);
    for (std::size_t i = 0; i < detail.pixels.size(); ++i)
      detail.pixels[i] =
          float(maps[0][i] + c[0] * (maps[1][i] - maps[0][i]) + c[1] * (maps[2][i] - maps[0][i]));
  }
  const auto& primitive = glb.json["meshes"][0]["primitives"][0];
  const auto texcoords = glb.floats(primitive["attributes"]["TEXCOORD_0"].get<int>());
  const std::size_t n = texcoords.size() / 2;
  const test::UvLocator locator(layout, model.triangle_uvs);
  Expected out;
  out.positions.assign(3 * n, 0.0);
  std::vector<Eigen::Vector3d> point(n, Eigen::Vector3d::Zero()),
      normal(n, Eigen::Vector3d::Zero()), rest(n, Eigen::Vector3d::Zero());
  std::vector<double> height(n, 0.0);
  std::map<std::array<long long, 3>, std::pair<double, int>> seam_heights;
  std::vector<std::array<long long, 3>> key(n);
  for (std::size_t o = 0; o < n; ++o) {
    const double u = texcoords[2 * o], v = 1.0 - texcoords[2 * o + 1];
    // Subdivided vertices on an edge of a small UV triangle: float UVs, flipped (1 - v).
    const auto [triangle, bary] = locator.find(u, v, 2e-4);
    if (triangle < 0) {
      ++out.unlocated;
      continue;
    }
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t vtx = model.triangles[3 * static_cast<std::size_t>(triangle) + k];
      for (int d = 0; d < 3; ++d) {
        point[o][d] += bary[k] * rig[3 * vtx + d];
        rest[o][d] += bary[k] * model.neutral[3 * vtx + d];
        normal[o][d] += bary[k] * normals[3 * vtx + d];
      }
    }
    normal[o].normalize();
    if (!maps.empty()) height[o] = sample_displacement(detail, texels.triangle, float(u), float(v));
    for (int d = 0; d < 3; ++d) key[o][d] = std::llround(rest[o][d] * 1000.0);
    auto& [sum, count] = seam_heights[key[o]];
    sum += height[o];
    ++count;
  }
  for (std::size_t o = 0; o < n; ++o) {
    const auto& [sum, count] = seam_heights[key[o]];
    const double h = sum / count;
    out.max_height = std::max(out.max_height, std::abs(h));
    for (int d = 0; d < 3; ++d) out.positions[3 * o + d] = point[o][d] + h * normal[o][d];
  }
  return out;
}

double max_difference(const std::vector<double>& a, const std::vector<double>& b) {
  double worst = 0.0;
  for (std::size_t i = 0; i < a.size() && i < b.size(); ++i)
    worst = std::max(worst, std::abs(a[i] - b[i]));
  return a.size() == b.size() ? worst : 1e9;
}

// The animation: the take's times, curves and head pose, frame for frame.
void check_animation(const test::Glb& glb, const TakeFrames& frames, TakeId take) {
  ASSERT_EQ(glb.json["animations"].size(), 1u);
  const auto& anim = glb.json["animations"][0];
  EXPECT_EQ(anim["name"], "take_" + std::to_string(take));
  const auto& nodes = glb.json["nodes"];
  ASSERT_EQ(nodes.size(), 2u);
  EXPECT_EQ(nodes[0]["children"], nlohmann::json::array({1}));
  EXPECT_EQ(nodes[1]["mesh"], 0);
  std::map<std::string, std::vector<float>> output;
  int input = -1;
  for (const auto& ch : anim["channels"]) {
    const auto& sampler = anim["samplers"][ch["sampler"].get<int>()];
    EXPECT_EQ(sampler["interpolation"], "LINEAR");
    EXPECT_EQ(ch["target"]["node"], ch["target"]["path"] == "weights" ? 1 : 0);
    input = sampler["input"];
    output[ch["target"]["path"]] = glb.floats(sampler["output"].get<int>());
  }
  ASSERT_EQ(output.size(), 3u);
  const auto times = glb.floats(input);
  ASSERT_EQ(times.size(), std::size_t(kFrames));
  const auto& accessor = glb.json["accessors"][input];
  EXPECT_EQ(accessor["min"][0].get<float>(), 0.0f);
  EXPECT_EQ(accessor["max"][0].get<float>(), times.back());
  double time_error = 0.0, pose_error = 0.0;
  const Eigen::Quaterniond flip(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()));
  for (int f = 0; f < kFrames; ++f) {
    time_error = std::max(time_error, std::abs(times[f] - (frames.times[f] - frames.times[0])));
    for (int k = 0; k < kArkitShapeCount; ++k)
      ASSERT_EQ(output["weights"][f * kArkitShapeCount + k], frames.curves[f][k]) << f << " " << k;
    const Eigen::Vector3d t = frames.poses[f].translation;
    const Eigen::Vector3d scene(t.x() / 1000, -t.y() / 1000, -t.z() / 1000);
    const Eigen::Quaterniond q = flip * frames.poses[f].rotation;
    const float* r = &output["rotation"][4 * f];
    const double dot = q.x() * r[0] + q.y() * r[1] + q.z() * r[2] + q.w() * r[3];
    pose_error = std::max(pose_error, 1.0 - std::abs(dot));
    for (int d = 0; d < 3; ++d)
      pose_error = std::max(pose_error, std::abs(output["translation"][3 * f + d] - scene[d]));
  }
  std::printf("animation: %d frames over %.3f s, time error %.2g s, pose error %.2g\n", kFrames,
              times.back(), time_error, pose_error);
  EXPECT_LT(time_error, 1e-6);
  EXPECT_LT(pose_error, 1e-6);
}

void check_validator(const fs::path& path) {
  std::string skip;
  const auto report = test::validate_gltf(path, skip);
  if (!report) {
    if (!skip.empty()) GTEST_SKIP() << skip;
    FAIL() << "the validator did not run";
  }
  std::cout << "gltf-validator " << (*report)["validatorVersion"] << ": " << (*report)["numErrors"]
            << " errors, " << (*report)["numWarnings"] << " warnings, " << (*report)["numInfos"]
            << " infos, " << (*report)["numHints"] << " hints; " << (*report)["messages"].dump()
            << "\ninfo " << (*report)["info"].dump() << "\n";
  EXPECT_EQ((*report)["numErrors"], 0) << (*report)["messages"].dump(1);
  EXPECT_EQ((*report)["numWarnings"], 0) << (*report)["messages"].dump(1);
  EXPECT_EQ((*report)["info"]["animationCount"], 1);
  EXPECT_EQ((*report)["info"]["hasMorphTargets"], true);
}

// assimp loads the file: `info` reports the animation and the head node; `info` does not list
// morph targets, so the file is also re-exported by assimp as glTF, which then has the 52.
void check_assimp(const fs::path& path) {
  if (std::string(FB_ASSIMP_PATH).empty()) {
    std::cout << "assimp (assimp-utils) is not installed: the assimp check is skipped\n";
    return;
  }
  const std::string assimp = FB_ASSIMP_PATH;
  const auto info = test::run_command(assimp + " info " + path.string(), test::Stderr::kMerged);
  ASSERT_EQ(info.exit_code, 0) << info.out;
  const auto from = info.out.find("Nodes:");
  std::cout << "assimp info: " << info.out.substr(from, info.out.find("Primitive") - from) << "\n";
  EXPECT_NE(info.out.find("Animations:         1"), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("Nodes:              2"), std::string::npos) << info.out;
  const fs::path again = path.parent_path() / "assimp" / "again.gltf";
  fs::create_directories(again.parent_path());
  const auto exported = test::run_command(
      assimp + " export " + path.string() + " " + again.string(), test::Stderr::kMerged);
  ASSERT_EQ(exported.exit_code, 0) << exported.out;
  const auto gltf = nlohmann::json::parse(std::ifstream(again));
  const std::size_t targets = gltf["meshes"][0]["primitives"][0]["targets"].size();
  std::printf("assimp: 1 animation, %zu morph targets read back\n", targets);
  EXPECT_EQ(targets, std::size_t(kArkitShapeCount));
}

bool has_nan(const std::string& text) {
  std::string lower = text;
  for (char& ch : lower) ch = char(std::tolower(static_cast<unsigned char>(ch)));
  for (std::size_t at = lower.find("nan"); at != std::string::npos;
       at = lower.find("nan", at + 1)) {
    const bool before = at > 0 && std::isalpha(static_cast<unsigned char>(lower[at - 1]));
    const bool after =
        at + 3 < lower.size() && std::isalpha(static_cast<unsigned char>(lower[at + 3]));
    if (!before && !after) return true;
  }
  return false;
}

std::string slurp(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

TEST_F(TakeGltf, WrinkleDetailMovesWithTheExpressionInTheAnimatedMesh) {
  const TakeId take = make_store(true, true, true);
  const fs::path out = dir_ / "out";
  double seconds = 0.0;
  const auto summary = export_take(take, out, &seconds);
  const std::string stem = "take_" + std::to_string(take);
  const fs::path path = out / (stem + ".glb");
  ASSERT_TRUE(fs::exists(path)) << summary.dump();
  ASSERT_TRUE(fs::exists(out / (stem + ".csv")));
  ASSERT_TRUE(fs::exists(out / (stem + "_detail_weights.csv")));
  EXPECT_EQ(summary["glb"], stem + ".glb");
  EXPECT_EQ(summary["glb_detail"], true);
  const std::string manifest = slurp(out / "manifest.json");
  const auto m = nlohmann::json::parse(manifest);
  EXPECT_EQ(m["details"]["glb"].get<std::string>().rfind(stem + ".glb: ", 0), 0u);
  EXPECT_EQ(m["what"], "livelink_csv+glb");
  EXPECT_NE(manifest.find("\"" + stem + ".glb\""), std::string::npos);  // in the file list
  EXPECT_FALSE(has_nan(manifest));

  const test::Glb glb = test::read_glb(path);
  EXPECT_FALSE(has_nan(glb.json.dump()));
  const auto& primitive = glb.json["meshes"][0]["primitives"][0];
  ASSERT_EQ(primitive["targets"].size(), std::size_t(kArkitShapeCount));
  EXPECT_FALSE(glb.json["materials"][0].contains("normalTexture"));  // the geometry carries it
  const std::size_t vertices =
      glb.json["accessors"][primitive["attributes"]["POSITION"].get<int>()]["count"];
  EXPECT_GT(vertices, std::size_t(model_->vertex_count) + 2000);  // subdivided under the detail
  check_animation(glb, frames_, take);

  // The map weights in the extras: the CSV's columns and numbers.
  const auto& extra = glb.json["animations"][0]["extras"]["detail_weights"];
  EXPECT_EQ(extra["columns"], nlohmann::json::array({"brow_raiser@1", "smile@2"}));
  ASSERT_EQ(extra["values"].size(), std::size_t(kFrames));
  std::vector<float> weights;
  for (const auto& ch : glb.json["animations"][0]["channels"])
    if (ch["target"]["path"] == "weights")
      weights =
          glb.floats(glb.json["animations"][0]["samplers"][ch["sampler"].get<int>()]["output"]);
  auto mapping = make_arkit_mapping(*model_);
  ASSERT_TRUE(mapping);
  double c_error = 0.0, worst = 0.0, largest_height = 0.0;
  for (int f : {0, 20, 30, 45}) {
    std::vector<float> a(static_cast<std::size_t>(model_->fitting_expression_count), 0.0f);
    mapping->to_model(frames_.curves[f], a);
    const auto c = map_weights(a);
    for (int e = 0; e < 2; ++e)
      c_error = std::max(c_error, std::abs(extra["values"][f][e].get<double>() - c[e]));
    const Expected expected = expected_mesh(*model_, uvs_, map_, glb, frames_.curves[f], maps_, c);
    ASSERT_EQ(expected.unlocated, 0);
    const double d = max_difference(animated_mesh(glb, weights, f), expected.positions);
    std::printf("frame %d: c = (%.4f, %.4f), detail up to %.3f mm, max difference %.2g mm\n", f,
                c[0], c[1], expected.max_height, d);
    worst = std::max(worst, d);
    largest_height = std::max(largest_height, expected.max_height);
  }
  std::printf(
      "take glb with detail: %zu glTF vertices (rig %d), %ju bytes, export %.2f s (CLI %.2f s), "
      "max difference %.2g mm, map weights error %.2g\n",
      vertices, model_->vertex_count, std::uintmax_t(fs::file_size(path)),
      summary["seconds"].get<double>(), seconds, worst, c_error);
  EXPECT_LT(worst, 0.01);          // mm, positions at four frames
  EXPECT_GT(largest_height, 0.3);  // the detail is there to be checked
  EXPECT_LT(c_error, 2e-6);        // 6 decimals

  check_validator(path);
  check_assimp(path);
}

TEST_F(TakeGltf, WithoutDetailTheRigIsAnimatedUnsubdivided) {
  const TakeId take = make_store(true, true, false);
  const fs::path out = dir_ / "out";
  double seconds = 0.0;
  const auto summary = export_take(take, out, &seconds);
  const fs::path path = out / ("take_" + std::to_string(take) + ".glb");
  ASSERT_TRUE(fs::exists(path)) << summary.dump();
  EXPECT_EQ(summary["glb_detail"], false);
  const test::Glb glb = test::read_glb(path);
  const auto& primitive = glb.json["meshes"][0]["primitives"][0];
  const std::size_t vertices =
      glb.json["accessors"][primitive["attributes"]["POSITION"].get<int>()]["count"];
  std::set<std::pair<std::uint32_t, std::uint32_t>> pairs;  // one glTF vertex per (vertex, UV)
  for (std::size_t c = 0; c < model_->triangle_uvs.size(); ++c)
    pairs.insert({model_->triangles[c], model_->triangle_uvs[c]});
  EXPECT_EQ(vertices, pairs.size());
  EXPECT_FALSE(glb.json["animations"][0].contains("extras"));
  check_animation(glb, frames_, take);
  std::vector<float> weights;
  for (const auto& ch : glb.json["animations"][0]["channels"])
    if (ch["target"]["path"] == "weights")
      weights =
          glb.floats(glb.json["animations"][0]["samplers"][ch["sampler"].get<int>()]["output"]);
  double worst = 0.0;
  for (int f : {0, 30, 45}) {
    const Expected expected = expected_mesh(*model_, uvs_, map_, glb, frames_.curves[f], {}, {});
    ASSERT_EQ(expected.unlocated, 0);
    worst = std::max(worst, max_difference(animated_mesh(glb, weights, f), expected.positions));
  }
  std::printf(
      "take glb without detail: %zu glTF vertices, %ju bytes, export %.2f s (CLI %.2f s), "
      "max difference %.2g mm\n",
      vertices, std::uintmax_t(fs::file_size(path)), summary["seconds"].get<double>(), seconds,
      worst);
  EXPECT_LT(worst, 0.01);
  check_validator(path);
}

// three.js, the web's glTF engine, plays the file in chromium (tests/export/
// play_take_threejs.mjs): at frame times and between frames, the influences and the head's world
// transform it evaluates are the take's, interpolated as glTF's LINEAR says (lerp; slerp).
TEST_F(TakeGltf, ThreeJsPlaysTheTakeAsRecorded) {
  if (std::string(FB_NODE_PATH).empty())
    GTEST_SKIP() << "node is not installed (scripts/install-deps installs it)";
  const TakeId take = make_store(true, true, false);
  const fs::path out = dir_ / "out";
  export_take(take, out);
  const fs::path path = out / ("take_" + std::to_string(take) + ".glb");
  ASSERT_TRUE(fs::exists(path));
  // (frame, fraction of the way to the next frame)
  const std::vector<std::pair<int, double>> samples = {
      {0, 0.0}, {17, 0.0}, {30, 0.5}, {44, 0.25}, {kFrames - 1, 0.0}};
  auto time_of = [&](int f) { return frames_.times[f] - frames_.times[0]; };
  std::string list;
  for (const auto& [f, a] : samples) {
    const double t = a == 0.0 ? time_of(f) : time_of(f) + a * (time_of(f + 1) - time_of(f));
    char text[32];
    std::snprintf(text, sizeof text, "%s%.9g", list.empty() ? "" : ",", t);
    list += text;
  }
  const auto run = test::run_command(std::string(FB_NODE_PATH) + " " + FB_PLAY_TAKE_SCRIPT + " " +
                                         FB_THREEJS_NPM_DIR + " " + path.string() + " " + list,
                                     test::Stderr::kToLog);
  if (run.exit_code == 77) GTEST_SKIP() << "chromium is not installed (apt-get install chromium)";
  ASSERT_EQ(run.exit_code, 0) << run.out;
  const auto played = nlohmann::json::parse(run.out, nullptr, false);
  ASSERT_FALSE(played.is_discarded()) << run.out;
  ASSERT_EQ(played["names"].size(), std::size_t(kArkitShapeCount));
  for (int k = 0; k < kArkitShapeCount; ++k) EXPECT_EQ(played["names"][k], kArkitNames[k]);
  const Eigen::Quaterniond flip(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()));
  // The head's pose at frame f in the scene frame (gltf_animation.hpp): (x, -y, -z) / 1000.
  auto position = [&](int f) -> Eigen::Vector3d {
    const Eigen::Vector3d t = frames_.poses[f].translation;
    return Eigen::Vector3d(t.x(), -t.y(), -t.z()) / 1000.0;
  };
  auto rotation = [&](int f) { return Eigen::Quaterniond(flip * frames_.poses[f].rotation); };
  double weight_error = 0.0, position_error = 0.0, rotation_error = 0.0, largest_weight = 0.0;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const int f = samples[i].first;
    const double a = samples[i].second;
    const int g = a == 0.0 ? f : f + 1;
    const auto& at = played["at"][i];
    for (int k = 0; k < kArkitShapeCount; ++k) {
      const double w = (1 - a) * frames_.curves[f][k] + a * frames_.curves[g][k];
      largest_weight = std::max(largest_weight, w);
      weight_error = std::max(weight_error, std::abs(at["weights"][k].get<double>() - w));
    }
    const Eigen::Vector3d p = (1 - a) * position(f) + a * position(g);
    for (int d = 0; d < 3; ++d)
      position_error = std::max(position_error, std::abs(at["position"][d].get<double>() - p[d]));
    // |q - r| or |q + r| (the same rotation): about half the angle between them, in radians.
    const Eigen::Vector4d q = rotation(f).slerp(a, rotation(g)).coeffs();  // x y z w
    Eigen::Vector4d r;
    for (int d = 0; d < 4; ++d) r[d] = at["quaternion"][d].get<double>();
    rotation_error = std::max(rotation_error, std::min((q - r).norm(), (q + r).norm()));
  }
  std::printf(
      "three.js r%s plays take_%u.glb (%.3f s): at %zu times (2 between frames) the influences "
      "are the take's within %.2g (largest %.2f), the head within %.2g m and %.2g (quaternion)\n",
      played["three"].get<std::string>().c_str(), unsigned(take), played["duration"].get<double>(),
      samples.size(), weight_error, largest_weight, position_error, rotation_error);
  EXPECT_GT(largest_weight, 0.1);  // the take moves, so the comparison means something
  EXPECT_LT(weight_error, 1e-5);
  EXPECT_LT(position_error, 1e-6);  // metres
  EXPECT_LT(rotation_error, 1e-6);  // about half the angle, radians
}

TEST_F(TakeGltf, WithoutSessionRigOrUsableTimesTheCsvStandsAndTheManifestSaysWhy) {
  const TakeId lone = make_store(false, false, false);
  const TakeId unrigged = make_store(true, false, false);
  frames_.times[7] = frames_.times[6];  // a clock that stood still: glTF needs increasing times
  const TakeId stalled = make_store(true, true, false);
  struct Case {
    TakeId take;
    const char* why;
  };
  for (const Case& c : {Case{lone, "none: the take records no session"},
                        Case{unrigged, "subject has no rig to animate (build one: facebooth rig"},
                        Case{stalled, "none: the take cannot be animated: frame 7's time ("}}) {
    const fs::path out = dir_ / ("out" + std::to_string(c.take));
    const auto summary = export_take(c.take, out);
    EXPECT_TRUE(fs::exists(out / ("take_" + std::to_string(c.take) + ".csv")));
    EXPECT_FALSE(fs::exists(out / ("take_" + std::to_string(c.take) + ".glb")));
    EXPECT_TRUE(summary["glb"].is_null());
    const std::string manifest = slurp(out / "manifest.json");
    const auto m = nlohmann::json::parse(manifest);
    EXPECT_NE(m["details"]["glb"].get<std::string>().find(c.why), std::string::npos)
        << m["details"]["glb"];
    EXPECT_EQ(summary["glb_note"], m["details"]["glb"]);
    EXPECT_EQ(m["what"], "livelink_csv");
    EXPECT_FALSE(has_nan(manifest));
  }
}

}  // namespace
}  // namespace fb
