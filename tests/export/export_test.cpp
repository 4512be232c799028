// Exports of a synthetic subject (the face model with a random identity): FaceWarehouse folder
// and its import, glTF checked by the Khronos validator and loaded by assimp, OBJ/PLY,
// manifests with checksums, and exports that are never visible half-written.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>

#include "algo/tracking/arkit.hpp"
#include "storage/asset_files.hpp"
#include "storage/durable_file.hpp"
#include "storage/export/arkit_rig.hpp"
#include "storage/export/export_folder.hpp"
#include "storage/export/export_session.hpp"
#include "storage/export/facewarehouse.hpp"
#include "storage/export/gltf.hpp"
#include "storage/export/mesh_files.hpp"
#include "storage/export/mesh_geometry.hpp"
#include "storage/export/png_file.hpp"
#include "storage/export/synthetic_subject.hpp"
#include "tests/common/gltf_validator.hpp"
#include "tests/common/run_command.hpp"
#include "tests/export/glb_reader.hpp"

namespace fb {
namespace {

namespace fs = std::filesystem;

test::CommandRun run(const std::string& command) {
  return test::run_command(command, test::Stderr::kMerged);
}

class Export : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    auto model = load_face_model();
    ASSERT_TRUE(model) << model.error().message;
    SyntheticSubjectOptions options;
    options.seed = 5;
    auto subject = make_synthetic_subject(*model, options);
    ASSERT_TRUE(subject) << subject.error().message;
    subject_ = std::make_unique<SyntheticSubject>(std::move(*subject));
    expression_count_ = model->expression_count;
    uvs_.uvs = model->atlas_uvs();  // what use_face_model_uvs() exports
    uvs_.triangle_uvs = model->triangle_uvs;
  }
  static void TearDownTestSuite() { subject_.reset(); }

  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("fb-export-" +
            std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()) + "-" +
            std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  ExportSummary export_as(ExportFormat format, const std::string& name,
                          std::optional<ShapeNames> names = std::nullopt) {
    ExportRequest request;
    request.format = format;
    request.out = dir_ / name;
    request.names = names;
    ExportContent content = synthetic_content(*subject_, 5, "facemodel.fbfm");
    content.uvs = uvs_;
    auto summary = export_content(content, request);
    EXPECT_TRUE(summary) << summary.error().message;
    return summary ? *summary : ExportSummary{};
  }

  static std::unique_ptr<SyntheticSubject> subject_;
  static MeshUvs uvs_;  // the face model's UV layout
  static int expression_count_;
  fs::path dir_;
};
std::unique_ptr<SyntheticSubject> Export::subject_;
MeshUvs Export::uvs_;
int Export::expression_count_ = 0;

// Apple's 52 ARKit blendshapes in the order ARFaceAnchor.BlendShapeLocation's documentation
// lists them (left eye, right eye, mouth and jaw, brows/cheeks/nose, tongue); written out here
// rather than taken from kArkitNames, so the test checks the table.
const std::vector<std::string> kAppleOrder = {
    "eyeBlinkLeft",      "eyeLookDownLeft",    "eyeLookInLeft",
    "eyeLookOutLeft",    "eyeLookUpLeft",      "eyeSquintLeft",
    "eyeWideLeft",       "eyeBlinkRight",      "eyeLookDownRight",
    "eyeLookInRight",    "eyeLookOutRight",    "eyeLookUpRight",
    "eyeSquintRight",    "eyeWideRight",       "jawForward",
    "jawLeft",           "jawRight",           "jawOpen",
    "mouthClose",        "mouthFunnel",        "mouthPucker",
    "mouthLeft",         "mouthRight",         "mouthSmileLeft",
    "mouthSmileRight",   "mouthFrownLeft",     "mouthFrownRight",
    "mouthDimpleLeft",   "mouthDimpleRight",   "mouthStretchLeft",
    "mouthStretchRight", "mouthRollLower",     "mouthRollUpper",
    "mouthShrugLower",   "mouthShrugUpper",    "mouthPressLeft",
    "mouthPressRight",   "mouthLowerDownLeft", "mouthLowerDownRight",
    "mouthUpperUpLeft",  "mouthUpperUpRight",  "browDownLeft",
    "browDownRight",     "browInnerUp",        "browOuterUpLeft",
    "browOuterUpRight",  "cheekPuff",          "cheekSquintLeft",
    "cheekSquintRight",  "noseSneerLeft",      "noseSneerRight",
    "tongueOut"};

using test::Glb;
using test::read_glb;

std::optional<nlohmann::json> validate(const fs::path& glb, std::string& skip) {
  return test::validate_gltf(glb, skip);
}

TEST_F(Export, SyntheticSubjectIsTheRigAtKnownWeights) {
  const auto& s = *subject_;
  ASSERT_EQ(s.rig.shape_count(), expression_count_);
  ASSERT_EQ(s.poses.size(), 20u);
  EXPECT_EQ(s.poses[0].positions, s.rig.neutral);
  // Pose i = neutral + sum_j w_j (shape_j - neutral).
  for (int p : {1, 7, 19}) {
    double worst = 0.0;
    for (std::size_t i = 0; i < s.rig.neutral.size(); ++i) {
      double v = s.rig.neutral[i];
      for (int j = 0; j < s.rig.shape_count(); ++j) {
        v += s.pose_weights[p][j] * (s.rig.shapes[j][i] - s.rig.neutral[i]);
      }
      worst = std::max(worst, std::abs(v - s.poses[p].positions[i]));
    }
    EXPECT_LT(worst, 1e-3) << "pose " << p;
  }
}

TEST_F(Export, FaceWarehouseFolderRoundTripsThroughImport) {
  const auto summary = export_as(ExportFormat::kFaceWarehouse, "fw");
  const fs::path tester = summary.path / "Tester_1";
  const int nv = subject_->rig.vertex_count();
  const int ns = subject_->rig.shape_count();
  const int nf = static_cast<int>(subject_->rig.triangles.size() / 3);
  // shape.bs: header + (K+1) x nVerts x 3 floats, neutral first.
  auto bs = read_file_bytes(tester / "Blendshape" / "shape.bs");
  ASSERT_TRUE(bs);
  ASSERT_EQ(bs->size(), 12u + std::size_t(ns + 1) * nv * 12);
  std::int32_t header[3];
  std::memcpy(header, bs->data(), 12);
  EXPECT_EQ(header[0], ns);
  EXPECT_EQ(header[1], nv);
  EXPECT_EQ(header[2], nf);
  float first;
  std::memcpy(&first, bs->data() + 12, 4);
  EXPECT_EQ(first, subject_->rig.neutral[0]);
  for (int k = 0; k <= ns; ++k) {
    EXPECT_TRUE(fs::exists(tester / "Blendshape" / ("shape_" + std::to_string(k) + ".obj")));
  }
  EXPECT_FALSE(fs::exists(tester / "Blendshape" / ("shape_" + std::to_string(ns + 1) + ".obj")));
  for (int p = 0; p < 20; ++p) {
    EXPECT_TRUE(fs::exists(tester / "TrainingPose" / ("pose_" + std::to_string(p) + ".obj")));
  }
  auto verified = verify_export_folder(summary.path);
  ASSERT_TRUE(verified) << verified.error().message;
  EXPECT_EQ(verified->size(), std::size_t(ns + 1 + 1 + 1 + 20));  // objs, .bs, names, poses

  auto imported = import_facewarehouse(summary.path);
  ASSERT_TRUE(imported) << imported.error().message;
  ASSERT_EQ(imported->size(), 1u);
  const auto& t = imported->front();
  EXPECT_EQ(t.number, 1);
  EXPECT_EQ(t.rig.neutral, subject_->rig.neutral);
  EXPECT_EQ(t.rig.shapes, subject_->rig.shapes);
  EXPECT_EQ(t.rig.triangles, subject_->rig.triangles);
  EXPECT_EQ(t.rig.shape_names, subject_->rig.shape_names);
  ASSERT_EQ(t.poses.size(), 20u);
  for (int p = 0; p < 20; ++p) {
    EXPECT_EQ(t.poses[p].positions, subject_->poses[p].positions) << p;  // exact float text
  }

  // The manifest says what the folder holds and how it differs from FaceWarehouse itself.
  auto manifest = nlohmann::json::parse(std::ifstream(summary.path / "manifest.json"));
  const auto& d = manifest["details"];
  EXPECT_EQ(d["names"], "model");
  EXPECT_NE(d["topology"].get<std::string>().find("ICT FaceKit skin"), std::string::npos);
  EXPECT_NE(d["topology"].get<std::string>().find("11248 vertices, 22288 triangles"),
            std::string::npos)
      << d["topology"];
  EXPECT_NE(d["units"].get<std::string>().find("millimetres"), std::string::npos);
  std::string expressions = "shape_1..shape_" + std::to_string(ns) + " = ";
  for (int j = 0; j < ns; ++j) expressions += (j ? "," : "") + subject_->rig.shape_names[j];
  EXPECT_EQ(d["expressions"], expressions);
  const std::string differs = d["differs_from_facewarehouse"];
  EXPECT_NE(differs.find("11,510-vertex mesh and 46"), std::string::npos) << differs;
  EXPECT_NE(differs.find("11248 vertices and " + std::to_string(ns) + " blendshapes"),
            std::string::npos)
      << differs;
}

TEST_F(Export, FaceWarehouseImportRejectsBrokenFolders) {
  const auto summary = export_as(ExportFormat::kFaceWarehouse, "fw");
  const fs::path bs = summary.path / "Tester_1" / "Blendshape" / "shape.bs";
  fs::resize_file(bs, fs::file_size(bs) - 100);
  auto truncated = import_facewarehouse(summary.path);
  ASSERT_FALSE(truncated);
  EXPECT_NE(truncated.error().message.find("truncated"), std::string::npos)
      << truncated.error().message;
  EXPECT_FALSE(import_facewarehouse(dir_ / "nothing-here"));
  fs::create_directories(dir_ / "empty");
  auto empty = import_facewarehouse(dir_ / "empty");
  ASSERT_FALSE(empty);
  EXPECT_NE(empty.error().message.find("Tester_"), std::string::npos);
  // Original FaceWarehouse OBJs carry texture coordinates and quads.
  auto quad = parse_obj("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/1 -1/1\n", "q");
  ASSERT_TRUE(quad) << quad.error().message;
  EXPECT_EQ(quad->face_count, 1);
  EXPECT_EQ(quad->mesh.triangles, (std::vector<std::uint32_t>{0, 1, 2, 0, 2, 3}));
  auto bad = parse_obj("v 0 0 0\nf 1 2 3\n", "bad.obj");
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().message.find("line 2"), std::string::npos);
}

TEST_F(Export, SessionExportCarriesColourFramesAndLandmarks) {
  auto store = SessionStore::open(dir_ / "store");
  ASSERT_TRUE(store);
  auto session = store_synthetic_subject(*store, *subject_, "synthetic");
  ASSERT_TRUE(session) << session.error().message;
  auto content = load_session_content(*store, *session);
  ASSERT_TRUE(content) << content.error().message;
  ASSERT_EQ(content->poses.size(), 20u);
  EXPECT_EQ(content->poses[3].positions, subject_->poses[3].positions);
  EXPECT_EQ(content->source.at("session"), std::to_string(*session));
  ExportRequest request;
  request.out = dir_ / "fw";
  auto summary = export_content(*content, request);
  ASSERT_TRUE(summary) << summary.error().message;
  const fs::path pose = summary->path / "Tester_1" / "TrainingPose";
  auto png = read_file_bytes(pose / "pose_4.png");
  ASSERT_TRUE(png);
  auto image = decode_png(*png);
  ASSERT_TRUE(image) << image.error().message;
  auto capture = store->read_capture(*session, 4);
  ASSERT_TRUE(capture);
  const auto& color = capture->frames.front().color;
  ASSERT_EQ(image->width, color.width);
  EXPECT_EQ(std::memcmp(image->pixels.data(), color.pixels.data(), color.pixels.size() * 3), 0);
  EXPECT_TRUE(fs::exists(pose / "pose_4.land"));
  auto manifest = read_file_bytes(summary->path / "manifest.json");
  auto j = nlohmann::json::parse(manifest->begin(), manifest->end());
  EXPECT_EQ(j["what"], "facewarehouse");
  EXPECT_EQ(j["source"]["session"], std::to_string(*session));
  EXPECT_EQ(j["versions"]["store_schema"], kSessionStoreSchemaVersion);
  EXPECT_EQ(j["files"].size(), std::size_t(subject_->rig.shape_count() + 3 + 20 * 3));
  // A session without a rig says what to do.
  auto bare = store->create_session(*store->add_subject("no rig"), {"a"});
  auto no_rig = load_session_content(*store, *bare);
  ASSERT_FALSE(no_rig);
  EXPECT_NE(no_rig.error().message.find("no rig"), std::string::npos);
}

// Issue 35: a session with only its neutral fitted could not be exported (no rig, and rigging
// needs an expression). Its neutral exports as OBJ, PLY and a glTF without morph targets that
// still validates; FaceWarehouse (a blendshape set) says what to do instead.
TEST_F(Export, NeutralOnlySessionExportsItsNeutral) {
  auto store = SessionStore::open(dir_ / "store");
  ASSERT_TRUE(store);
  auto subject = store->add_subject("neutral only");
  ASSERT_TRUE(subject);
  auto session = store->create_session(*subject, {"neutral", "smile"});
  ASSERT_TRUE(session);
  const MeshData& neutral = subject_->poses[0];
  ASSERT_TRUE(store->add_mesh(*session, 0, MeshRole::kNeutral, "neutral", neutral));
  auto content = load_session_content(*store, *session);
  ASSERT_TRUE(content) << content.error().message;
  EXPECT_EQ(content->rig.shape_count(), 0);
  EXPECT_EQ(content->rig.neutral, neutral.positions);
  ASSERT_EQ(content->poses.size(), 1u);

  auto export_to = [&](ExportFormat format, const std::string& name) {
    ExportRequest request;
    request.format = format;
    request.out = dir_ / name;
    return export_content(*content, request);
  };
  for (auto format : {ExportFormat::kObj, ExportFormat::kPly}) {
    const std::string ext = to_string(format);
    auto summary = export_to(format, ext);
    ASSERT_TRUE(summary) << summary.error().message;
    EXPECT_TRUE(verify_export_folder(summary->path));
    EXPECT_TRUE(fs::exists(summary->path / ("neutral." + ext)));
    EXPECT_TRUE(fs::exists(summary->path / "poses" / ("pose_0." + ext)));
    EXPECT_FALSE(fs::exists(summary->path / "blendshapes"));
    // neutral, pose 0, manifest (+ face.mtl for OBJ)
    EXPECT_EQ(summary->files, format == ExportFormat::kObj ? 4 : 3) << ext;
  }
  auto back = read_obj(dir_ / "obj" / "neutral.obj");
  ASSERT_TRUE(back);
  EXPECT_EQ(back->mesh.positions, neutral.positions);
  EXPECT_EQ(back->mesh.triangles, neutral.triangles);

  auto glb_summary = export_to(ExportFormat::kGlb, "glb");
  ASSERT_TRUE(glb_summary) << glb_summary.error().message;
  const fs::path glb = glb_summary->path / (content->name + ".glb");
  auto bytes = read_file_bytes(glb);
  ASSERT_TRUE(bytes);
  std::uint32_t head[5];
  std::memcpy(head, bytes->data(), sizeof head);
  auto j = nlohmann::json::parse(bytes->begin() + 20, bytes->begin() + 20 + head[3]);
  EXPECT_FALSE(j["meshes"][0]["primitives"][0].contains("targets"));
  EXPECT_FALSE(j["meshes"][0].contains("weights"));
  EXPECT_EQ(j["accessors"][1]["count"], neutral.positions.size() / 3);

  auto fw = export_to(ExportFormat::kFaceWarehouse, "fw");
  ASSERT_FALSE(fw);
  EXPECT_NE(fw.error().message.find("use --format obj, ply or glb"), std::string::npos)
      << fw.error().message;

  if (std::string(FB_NODE_PATH).empty()) GTEST_SKIP() << "node is not installed";
  ASSERT_TRUE(fs::exists(FB_GLTF_VALIDATOR_MODULE))
      << "gltf-validator is missing: run ctest (fixture export_install_gltf_validator)";
  const auto validated = run(std::string(FB_NODE_PATH) + " " + FB_GLTF_VALIDATE_SCRIPT + " " +
                             FB_GLTF_VALIDATOR_MODULE + " " + glb.string());
  ASSERT_EQ(validated.exit_code, 0) << validated.out;
  auto report = nlohmann::json::parse(validated.out, nullptr, false);
  ASSERT_FALSE(report.is_discarded()) << validated.out;
  std::cout << "neutral-only glb: " << report["numErrors"] << " errors, " << report["numWarnings"]
            << " warnings\n";
  EXPECT_EQ(report["numErrors"], 0) << report["messages"].dump(1);
}

// The default glTF export as engines and DCC tools take it: Apple's 52 ARKit targets in Apple's
// order, normals on the neutral and in every target, the face model's UVs (seams split), a PBR
// material; the Khronos validator reports 0 errors and 0 warnings, and assimp loads it.
TEST_F(Export, GlbHasArkitTargetsNormalsUvsAndPassesTheKhronosValidator) {
  const auto summary = export_as(ExportFormat::kGlb, "glb");
  const fs::path glb_path = summary.path / "synthetic5.glb";
  ASSERT_TRUE(fs::exists(glb_path));
  ASSERT_TRUE(verify_export_folder(summary.path));
  EXPECT_EQ(summary.blendshapes, 52);

  // Our own reading of the container: header, names, attributes, material.
  const Glb glb = read_glb(glb_path);
  std::uint32_t head[3];
  std::memcpy(head, glb.bytes.data(), sizeof head);
  EXPECT_EQ(head[0], 0x46546C67u);
  EXPECT_EQ(head[1], 2u);
  EXPECT_EQ(head[2], glb.bytes.size());
  const auto& mesh = glb.json["meshes"][0];
  const auto& primitive = mesh["primitives"][0];
  ASSERT_EQ(mesh["extras"]["targetNames"].get<std::vector<std::string>>(), kAppleOrder);
  ASSERT_EQ(primitive["targets"].size(), 52u);
  EXPECT_EQ(mesh["weights"].size(), 52u);
  for (const auto& target : primitive["targets"]) {
    EXPECT_TRUE(target.contains("POSITION"));
    EXPECT_TRUE(target.contains("NORMAL"));
  }
  ASSERT_TRUE(primitive["attributes"].contains("NORMAL"));
  ASSERT_TRUE(primitive["attributes"].contains("TEXCOORD_0"));
  EXPECT_FALSE(primitive["attributes"].contains("TEXCOORD_1"));
  ASSERT_EQ(glb.json["materials"].size(), 1u);
  EXPECT_EQ(glb.json["materials"][0]["pbrMetallicRoughness"]["metallicFactor"], 0.0);
  EXPECT_EQ(primitive["material"], 0);

  // One glTF vertex per (vertex, UV) pair: 11,248 vertices + 214 seam copies.
  const int position = primitive["attributes"]["POSITION"];
  const std::size_t vertices = glb.json["accessors"][position]["count"];
  std::set<std::pair<std::uint32_t, std::uint32_t>> pairs;
  for (std::size_t c = 0; c < uvs_.triangle_uvs.size(); ++c)
    pairs.insert({subject_->rig.triangles[c], uvs_.triangle_uvs[c]});
  EXPECT_EQ(vertices, pairs.size());
  EXPECT_GT(vertices, std::size_t(subject_->rig.vertex_count()));

  // The combined shapes: browInnerUp = browInnerUp_L + browInnerUp_R (deltas), tongueOut zero.
  auto target_floats = [&](int t, const char* attribute) {
    return glb.floats(primitive["targets"][t][attribute].get<int>());
  };
  const auto brow = target_floats(43, "POSITION");
  const auto tongue = target_floats(51, "POSITION");
  double brow_max = 0, tongue_max = 0;
  for (float v : brow) brow_max = std::max(brow_max, double(std::abs(v)));
  for (float v : tongue) tongue_max = std::max(tongue_max, double(std::abs(v)));
  const int brow_l = static_cast<int>(std::find(subject_->rig.shape_names.begin(),
                                                subject_->rig.shape_names.end(), "browInnerUp_L") -
                                      subject_->rig.shape_names.begin());
  double sum_max = 0;
  for (std::size_t i = 0; i < subject_->rig.neutral.size(); ++i) {
    const double l = subject_->rig.shapes[brow_l][i] - subject_->rig.neutral[i];
    const double r = subject_->rig.shapes[brow_l + 1][i] - subject_->rig.neutral[i];
    sum_max = std::max(sum_max, std::abs(l + r) * 0.001);
  }
  std::printf(
      "glb: %zu vertices (%d + seam copies), browInnerUp max delta %.4f m (L+R %.4f), "
      "tongueOut max %.1g\n",
      vertices, subject_->rig.vertex_count(), brow_max, sum_max, tongue_max);
  EXPECT_NEAR(brow_max, sum_max, 1e-6);
  EXPECT_GT(brow_max, 0.001);
  EXPECT_EQ(tongue_max, 0.0);
  // Neutral normals are unit length and face out over the face (+Z on average).
  const auto normals = glb.floats(primitive["attributes"]["NORMAL"].get<int>());
  double worst_length = 0, mean_z = 0;
  for (std::size_t v = 0; v < vertices; ++v) {
    const double x = normals[3 * v], y = normals[3 * v + 1], z = normals[3 * v + 2];
    worst_length = std::max(worst_length, std::abs(std::sqrt(x * x + y * y + z * z) - 1.0));
    mean_z += z / double(vertices);
  }
  EXPECT_LT(worst_length, 1e-5);
  const auto jaw_normals = target_floats(17, "NORMAL");  // jawOpen turns the chin's normals
  double jaw_normal_max = 0;
  for (float v : jaw_normals) jaw_normal_max = std::max(jaw_normal_max, double(std::abs(v)));
  std::printf("glb: normals |n|-1 <= %.2g, mean z %.3f; jawOpen normal delta max %.3f\n",
              worst_length, mean_z, jaw_normal_max);
  EXPECT_GT(jaw_normal_max, 0.05);

  std::string skip;
  const auto report = validate(glb_path, skip);
  if (!report) {
    if (!skip.empty()) GTEST_SKIP() << skip;
    FAIL() << "the validator did not run";
  }
  const auto& info = (*report)["info"];
  std::cout << "gltf-validator " << (*report)["validatorVersion"] << ": " << (*report)["numErrors"]
            << " errors, " << (*report)["numWarnings"] << " warnings, " << (*report)["numInfos"]
            << " infos; info " << info.dump() << "\n";
  EXPECT_EQ((*report)["numErrors"], 0) << (*report)["messages"].dump(1);
  EXPECT_EQ((*report)["numWarnings"], 0) << (*report)["messages"].dump(1);
  EXPECT_EQ(info["maxUVs"], 1);
  EXPECT_EQ(info["hasMorphTargets"], true);
  EXPECT_EQ(info["materialCount"], 1);
  EXPECT_EQ(info["hasTextures"], false);  // no texture given: the plain skin material
  EXPECT_EQ(info["totalVertexCount"], vertices);

  if (std::string(FB_ASSIMP_PATH).empty()) GTEST_SKIP() << "assimp (assimp-utils) is not installed";
  const auto loaded = run(std::string(FB_ASSIMP_PATH) + " info " + glb_path.string());
  ASSERT_EQ(loaded.exit_code, 0) << loaded.out;
  EXPECT_NE(loaded.out.find(std::to_string(vertices)), std::string::npos) << loaded.out;
}

// One mapping for all: the ARKit rig an export writes, driven by ARKit curves a, is the face
// model rig driven by what the tracker's mapping (the VMC stream's) gives the model for a.
TEST_F(Export, ArkitRigIsTheStreamsMappingApplied) {
  auto model = load_face_model();
  ASSERT_TRUE(model);
  auto mapping = make_arkit_mapping(*model);  // what `track` and the daemon stream through
  ASSERT_TRUE(mapping);
  auto arkit = to_arkit_rig(subject_->rig);
  ASSERT_TRUE(arkit) << arkit.error().message;
  ASSERT_EQ(arkit->rig.shape_count(), kArkitShapeCount);
  for (int i = 0; i < kArkitShapeCount; ++i)
    EXPECT_EQ(arkit->rig.shape_names[i], kArkitNames[static_cast<std::size_t>(i)]);
  EXPECT_EQ(arkit->dropped.size(), 4u);  // cheekRaiser_L/R, PupilDilate_L/R
  std::array<float, kArkitShapeCount> a{};
  for (int i = 0; i < kArkitShapeCount; ++i) a[i] = 0.05f + 0.9f * float((i * 37) % 52) / 52.0f;
  std::vector<float> w(static_cast<std::size_t>(subject_->rig.shape_count()), 0.0f);
  mapping->to_model(a, w);
  double worst = 0.0;
  for (std::size_t k = 0; k < subject_->rig.neutral.size(); ++k) {
    double by_model = subject_->rig.neutral[k], by_arkit = subject_->rig.neutral[k];
    for (int j = 0; j < subject_->rig.shape_count(); ++j)
      by_model += w[j] * (subject_->rig.shapes[j][k] - subject_->rig.neutral[k]);
    for (int i = 0; i < kArkitShapeCount; ++i)
      by_arkit += a[i] * (arkit->rig.shapes[i][k] - arkit->rig.neutral[k]);
    worst = std::max(worst, std::abs(by_model - by_arkit));
  }
  std::printf("ARKit rig vs model rig under the stream's mapping: max difference %.2g mm\n", worst);
  EXPECT_LT(worst, 1e-3);
  // A rig whose names are not the face model's cannot be named as ARKit's: it says what to do.
  RigData other = subject_->rig;
  for (auto& name : other.shape_names) name = "shape_" + name;
  auto refused = to_arkit_rig(other);
  ASSERT_FALSE(refused);
  EXPECT_NE(refused.error().message.find("--names model"), std::string::npos);
}

// A texture in the UV layout (what `facebooth texture` stores, tests/texture has the real one)
// becomes the glTF material's baseColorTexture (the validator then reports hasTextures) and the
// OBJ's face.png + map_Kd, which assimp loads with the mesh.
TEST_F(Export, ATextureInTheUvLayoutReachesGltfAndObjMtl) {
  ColorImage checker;
  checker.resize(256, 256);
  for (int y = 0; y < 256; ++y)
    for (int x = 0; x < 256; ++x)
      checker.at(x, y) = ((x / 32 + y / 32) % 2) ? Rgb8{200, 150, 120} : Rgb8{90, 60, 50};
  auto png = encode_png(checker);
  ASSERT_TRUE(png);
  ExportContent content = synthetic_content(*subject_, 5, "facemodel.fbfm");
  content.uvs = uvs_;
  content.texture_png = *png;
  ExportRequest request;
  request.format = ExportFormat::kGlb;
  request.out = dir_ / "glb";
  auto glb_summary = export_content(content, request);
  ASSERT_TRUE(glb_summary) << glb_summary.error().message;
  const fs::path glb_path = glb_summary->path / "synthetic5.glb";
  const Glb glb = read_glb(glb_path);
  EXPECT_EQ(glb.json["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]["index"], 0);
  EXPECT_EQ(glb.json["images"][0]["mimeType"], "image/png");

  request.format = ExportFormat::kObj;
  request.out = dir_ / "obj";
  auto obj_summary = export_content(content, request);
  ASSERT_TRUE(obj_summary) << obj_summary.error().message;
  EXPECT_TRUE(fs::exists(obj_summary->path / "face.png"));
  std::ifstream mtl(obj_summary->path / "face.mtl");
  const std::string mtl_text((std::istreambuf_iterator<char>(mtl)), {});
  EXPECT_NE(mtl_text.find("map_Kd face.png"), std::string::npos) << mtl_text;

  std::string skip;
  const auto report = validate(glb_path, skip);
  if (report) {
    std::cout << "textured glb: " << (*report)["numErrors"] << " errors, "
              << (*report)["numWarnings"] << " warnings, " << (*report)["numInfos"]
              << " infos; hasTextures " << (*report)["info"]["hasTextures"] << "\n";
    EXPECT_EQ((*report)["numErrors"], 0) << (*report)["messages"].dump(1);
    EXPECT_EQ((*report)["numWarnings"], 0) << (*report)["messages"].dump(1);
    EXPECT_EQ((*report)["info"]["hasTextures"], true);
    EXPECT_EQ((*report)["info"]["maxUVs"], 1);
  } else if (skip.empty()) {
    FAIL() << "the validator did not run";
  }
  if (std::string(FB_ASSIMP_PATH).empty()) GTEST_SKIP() << "assimp (assimp-utils) is not installed";
  const auto info =
      run(std::string(FB_ASSIMP_PATH) + " info " + (obj_summary->path / "neutral.obj").string());
  ASSERT_EQ(info.exit_code, 0) << info.out;
  EXPECT_NE(info.out.find("face.png"), std::string::npos) << info.out;  // the diffuse texture
  if (!skip.empty()) GTEST_SKIP() << skip;
}

// Wrinkle detail (issue 40): the neutral's normal map as normalTexture next to the base colour,
// TANGENT per vertex (unit, w = +-1, bitangent along the layout's +v: glTF's -v), the validator
// clean; OBJ: norm in the MTL and every pose's maps in wrinkles/.
TEST_F(Export, WrinkleNormalMapReachesGltfWithTangentsAndObjMtl) {
  ColorImage color, normal;
  color.resize(64, 32);
  std::fill(color.pixels.begin(), color.pixels.end(), Rgb8{180, 140, 120});
  normal.resize(256, 128);
  for (int y = 0; y < 128; ++y)
    for (int x = 0; x < 256; ++x)
      normal.at(x, y) = (x / 16 + y / 16) % 2 ? Rgb8{160, 128, 250} : Rgb8{128, 128, 255};
  auto color_png = encode_png(color);
  auto normal_png = encode_png(normal);
  ASSERT_TRUE(color_png && normal_png);
  ExportContent content = synthetic_content(*subject_, 5, "facemodel.fbfm");
  content.uvs = uvs_;
  content.texture_png = *color_png;
  ASSERT_EQ(content.pose_names.front(), "neutral");
  content.pose_details.resize(content.poses.size());
  for (std::size_t i : {std::size_t{0}, std::size_t{3}}) {
    WrinkleDetailData& d = content.pose_details[i];
    d.width = 256;
    d.height = 128;
    d.displacement_mm.assign(256 * 128, i == 0 ? -0.25f : 0.5f);
    d.normal_png = *normal_png;
  }
  ExportRequest request;
  request.format = ExportFormat::kGlb;
  request.out = dir_ / "glb";
  auto glb_summary = export_content(content, request);
  ASSERT_TRUE(glb_summary) << glb_summary.error().message;
  const fs::path glb_path = glb_summary->path / "synthetic5.glb";
  const Glb glb = read_glb(glb_path);
  const auto& material = glb.json["materials"][0];
  EXPECT_EQ(material["pbrMetallicRoughness"]["baseColorTexture"]["index"], 0);
  EXPECT_EQ(material["normalTexture"]["index"], 1);
  ASSERT_EQ(glb.json["images"].size(), 2u);
  const auto& attributes = glb.json["meshes"][0]["primitives"][0]["attributes"];
  ASSERT_TRUE(attributes.contains("TANGENT"));
  const auto tangents = glb.floats(attributes["TANGENT"].get<int>());
  const auto normals = glb.floats(attributes["NORMAL"].get<int>());
  const auto positions = glb.floats(attributes["POSITION"].get<int>());
  const auto texcoords = glb.floats(attributes["TEXCOORD_0"].get<int>());
  ASSERT_EQ(tangents.size() / 4, normals.size() / 3);
  double worst_length = 0, worst_dot = 0;
  for (std::size_t v = 0; v < normals.size() / 3; ++v) {
    const Eigen::Vector3d t(tangents[4 * v], tangents[4 * v + 1], tangents[4 * v + 2]);
    const Eigen::Vector3d n(normals[3 * v], normals[3 * v + 1], normals[3 * v + 2]);
    worst_length = std::max(worst_length, std::abs(t.norm() - 1.0));
    worst_dot = std::max(worst_dot, std::abs(t.dot(n)));
    EXPECT_EQ(std::abs(tangents[4 * v + 3]), 1.0f);
  }
  // Per triangle: the bitangent of its first corner against the surface's direction of the
  // layout's +v (glTF texcoord v decreasing), and the tangent against +u.
  const auto& indices_accessor = glb.json["accessors"][0];
  const auto& view = glb.json["bufferViews"][indices_accessor["bufferView"].get<int>()];
  std::vector<std::uint32_t> tris(indices_accessor["count"].get<std::size_t>());
  std::memcpy(tris.data(),
              glb.bytes.data() + glb.bin_offset + view["byteOffset"].get<std::size_t>(),
              tris.size() * 4);
  int agree_u = 0, agree_v = 0, counted = 0;
  auto p = [&](std::uint32_t i) {
    return Eigen::Vector3d(positions[3 * i], positions[3 * i + 1], positions[3 * i + 2]);
  };
  auto q = [&](std::uint32_t i) {
    return Eigen::Vector2d(texcoords[2 * i], -texcoords[2 * i + 1]);
  };
  for (std::size_t t = 0; t + 2 < tris.size(); t += 3) {
    const auto a = tris[t], b = tris[t + 1], c = tris[t + 2];
    Eigen::Matrix<double, 3, 2> e;
    e << p(b) - p(a), p(c) - p(a);
    Eigen::Matrix2d f;
    f << q(b) - q(a), q(c) - q(a);
    if (std::abs(f.determinant()) < 1e-12) continue;
    const Eigen::Matrix<double, 3, 2> j = e * f.inverse();
    const Eigen::Vector3d tan(tangents[4 * a], tangents[4 * a + 1], tangents[4 * a + 2]);
    const Eigen::Vector3d n(normals[3 * a], normals[3 * a + 1], normals[3 * a + 2]);
    const Eigen::Vector3d bit = n.cross(tan) * tangents[4 * a + 3];
    ++counted;
    agree_u += tan.dot(j.col(0)) > 0;
    agree_v += bit.dot(j.col(1)) > 0;
  }
  std::printf("tangents: |t|-1 <= %.1g, |t.n| <= %.1g; +u agrees %d, +v agrees %d of %d\n",
              worst_length, worst_dot, agree_u, agree_v, counted);
  EXPECT_LT(worst_length, 1e-5);
  EXPECT_LT(worst_dot, 1e-5);
  EXPECT_GT(agree_u, 0.99 * counted);
  EXPECT_GT(agree_v, 0.99 * counted);

  request.format = ExportFormat::kObj;
  request.out = dir_ / "obj";
  auto obj_summary = export_content(content, request);
  ASSERT_TRUE(obj_summary) << obj_summary.error().message;
  std::ifstream mtl(obj_summary->path / "face.mtl");
  const std::string mtl_text((std::istreambuf_iterator<char>(mtl)), {});
  EXPECT_NE(mtl_text.find("norm face_normal.png"), std::string::npos) << mtl_text;
  EXPECT_TRUE(fs::exists(obj_summary->path / "face_normal.png"));
  EXPECT_TRUE(fs::exists(obj_summary->path / "wrinkles" / "pose_3_normal.png"));
  std::ifstream pgm(obj_summary->path / "wrinkles" / "pose_0_displacement.pgm", std::ios::binary);
  const std::string pgm_text((std::istreambuf_iterator<char>(pgm)), {});
  ASSERT_GT(pgm_text.size(), 20u);
  // The last sample: -0.25 mm = 32768 - 250 = 32518, big-endian.
  const auto hi = static_cast<unsigned char>(pgm_text[pgm_text.size() - 2]);
  const auto lo = static_cast<unsigned char>(pgm_text[pgm_text.size() - 1]);
  EXPECT_EQ(hi * 256 + lo, 32518);
  EXPECT_FALSE(fs::exists(obj_summary->path / "wrinkles" / "pose_1_normal.png"));

  std::string skip;
  const auto report = validate(glb_path, skip);
  if (!report) {
    if (!skip.empty()) GTEST_SKIP() << skip;
    FAIL() << "the validator did not run";
  }
  std::cout << "glb with normalTexture: " << (*report)["numErrors"] << " errors, "
            << (*report)["numWarnings"] << " warnings, " << (*report)["numInfos"] << " infos "
            << (*report)["messages"].dump() << "\n";
  EXPECT_EQ((*report)["numErrors"], 0) << (*report)["messages"].dump(1);
  EXPECT_EQ((*report)["numWarnings"], 0) << (*report)["messages"].dump(1);
  EXPECT_EQ((*report)["info"]["hasTextures"], true);
}

// --names model keeps the face model's shapes and names (what the glb held before ARKit names).
TEST_F(Export, GlbWithModelNamesKeepsTheRigsShapes) {
  const auto summary = export_as(ExportFormat::kGlb, "glb-model", ShapeNames::kModel);
  const Glb glb = read_glb(summary.path / "synthetic5.glb");
  EXPECT_EQ(glb.json["meshes"][0]["extras"]["targetNames"].get<std::vector<std::string>>(),
            subject_->rig.shape_names);
  auto manifest = nlohmann::json::parse(std::ifstream(summary.path / "manifest.json"));
  EXPECT_EQ(manifest["details"]["names"], "model");
}

// OBJ with the face model's UVs, normals and face.mtl, and PLY, both loaded by assimp.
TEST_F(Export, ObjWithMtlAndPlyFoldersLoadInAssimp) {
  for (auto format : {ExportFormat::kObj, ExportFormat::kPly}) {
    const std::string ext = format == ExportFormat::kObj ? "obj" : "ply";
    const auto summary = export_as(format, ext);
    ASSERT_TRUE(verify_export_folder(summary.path));
    EXPECT_TRUE(fs::exists(summary.path / ("neutral." + ext)));
    EXPECT_TRUE(fs::exists(summary.path / "poses" / ("pose_19." + ext)));
    EXPECT_TRUE(fs::exists(summary.path / "blendshapes" /
                           ("01_" + subject_->rig.shape_names[0] + "." + ext)));
    if (format == ExportFormat::kObj) {
      auto back = read_obj(summary.path / "neutral.obj");
      ASSERT_TRUE(back);
      EXPECT_EQ(back->mesh.positions, subject_->rig.neutral);
      EXPECT_EQ(back->mesh.triangles, subject_->rig.triangles);
      ASSERT_TRUE(fs::exists(summary.path / "face.mtl"));
      std::ifstream in(summary.path / "neutral.obj");
      std::string line;
      std::size_t vt = 0, vn = 0;
      bool mtllib = false, usemtl = false;
      while (std::getline(in, line)) {
        vt += line.rfind("vt ", 0) == 0;
        vn += line.rfind("vn ", 0) == 0;
        mtllib = mtllib || line == "mtllib face.mtl";
        usemtl = usemtl || line == "usemtl skin";
      }
      EXPECT_EQ(vt, uvs_.uvs.size() / 2);
      EXPECT_EQ(vn, std::size_t(subject_->rig.vertex_count()));
      EXPECT_TRUE(mtllib && usemtl);
    } else {
      const auto size = fs::file_size(summary.path / "neutral.ply");
      const std::size_t payload =
          std::size_t(subject_->rig.vertex_count()) * 12 + subject_->rig.triangles.size() / 3 * 13;
      EXPECT_GT(size, payload);
      EXPECT_LT(size, payload + 400);
    }
    if (std::string(FB_ASSIMP_PATH).empty()) continue;
    for (const std::string& file :
         {"neutral." + ext, "blendshapes/01_" + subject_->rig.shape_names[0] + "." + ext}) {
      const auto info =
          run(std::string(FB_ASSIMP_PATH) + " info " + (summary.path / file).string());
      ASSERT_EQ(info.exit_code, 0) << info.out;
      EXPECT_NE(info.out.find(std::to_string(subject_->rig.triangles.size() / 3)),
                std::string::npos)
          << info.out;
      if (format == ExportFormat::kObj) {
        // assimp read face.mtl (a material named skin) and the UV channel.
        EXPECT_NE(info.out.find("skin"), std::string::npos) << info.out;
        EXPECT_EQ(info.out.find("Warn"), std::string::npos) << info.out;
      }
      if (file.rfind("neutral", 0) == 0) std::cout << "assimp info " << file << ":\n" << info.out;
    }
  }
}

TEST_F(Export, InterruptedExportNeverLooksComplete) {
  const fs::path dest = dir_ / "out";
  {
    auto folder = ExportFolder::create(dest, false);
    ASSERT_TRUE(folder);
    ASSERT_TRUE(folder->write_text("a.txt", "partial"));
    EXPECT_FALSE(fs::exists(dest));  // only a hidden temporary exists while writing
  }                                  // destroyed without finish(): as if the export failed half-way
  EXPECT_FALSE(fs::exists(dest));
  for (const auto& e : fs::directory_iterator(dir_)) ADD_FAILURE() << "left behind: " << e.path();

  const auto first = export_as(ExportFormat::kGlb, "out");
  ExportRequest again;
  again.format = ExportFormat::kObj;
  again.out = dest;
  auto refused = export_content(synthetic_content(*subject_, 5, "m"), again);
  ASSERT_FALSE(refused);
  EXPECT_NE(refused.error().message.find("--force"), std::string::npos);
  EXPECT_TRUE(fs::exists(dest / "synthetic5.glb"));  // untouched
  again.overwrite = true;
  ASSERT_TRUE(export_content(synthetic_content(*subject_, 5, "m"), again));
  EXPECT_FALSE(fs::exists(dest / "synthetic5.glb"));
  EXPECT_TRUE(fs::exists(dest / "neutral.obj"));
  int entries = 0;
  for (const auto& e : fs::directory_iterator(dir_)) (void)e, ++entries;
  EXPECT_EQ(entries, 1);  // no temporaries or old copies
  EXPECT_TRUE(verify_export_folder(dest));
}

}  // namespace
}  // namespace fb
