// The wrinkle detail as geometry (issue 40 item 4): the subdivided, displaced mesh against known
// heights, on a plane (exact surface, closed refinement) and through the OBJ export of a
// synthetic subject read back by assimp and the project's OBJ reader.
#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Dense>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "algo/texture/texel_map.hpp"
#include "algo/wrinkles/detail_mesh.hpp"
#include "storage/asset_files.hpp"
#include "storage/export/export_session.hpp"
#include "storage/export/synthetic_subject.hpp"
#include "tests/common/run_command.hpp"
#include "tests/common/uv_locator.hpp"

namespace fb {
namespace {

namespace fs = std::filesystem;

// A 21 x 21 vertex plane, 2.5 mm apart (50 mm square), z = 0, UV = (x, y) / 50; a 100 x 100
// map (0.5 mm texels) with heights 0.3 + 0.2 sin(2 pi x / 6 mm) inside [15, 35]^2 mm, 0 outside.
float plane_height(double x, double y) {
  if (x < 15 || x > 35 || y < 15 || y > 35) return 0.0f;
  return static_cast<float>(0.3 + 0.2 * std::sin(2 * M_PI * x / 6.0));
}

TEST(DetailMesh, PlaneHeightsInsideExactSurfaceOutsideNoTJunctions) {
  std::vector<float> vertices, uvs;
  std::vector<std::uint32_t> triangles;
  for (int j = 0; j <= 20; ++j)
    for (int i = 0; i <= 20; ++i) {
      vertices.insert(vertices.end(), {2.5f * i, 2.5f * j, 0.0f});
      uvs.insert(uvs.end(), {i / 20.0f, j / 20.0f});
    }
  for (int j = 0; j < 20; ++j)
    for (int i = 0; i < 20; ++i) {
      const auto a = static_cast<std::uint32_t>(j * 21 + i), b = a + 1, c = a + 21, d = c + 1;
      triangles.insert(triangles.end(), {a, b, d, a, d, c});
    }
  FloatImage map;
  map.resize(100, 100);
  for (int y = 0; y < 100; ++y)
    for (int x = 0; x < 100; ++x)  // texel centre: u = (x + 0.5) / 100, v = 1 - (y + 0.5) / 100
      map.at(x, y) = plane_height(0.5 * (x + 0.5), 50.0 - 0.5 * (y + 0.5));
  DetailMeshInput in{vertices, triangles, uvs, triangles, &map};
  auto mesh = subdivided_detail_mesh(in);
  ASSERT_TRUE(mesh) << mesh.error().message;
  const std::size_t n = mesh->positions.size() / 3;
  std::printf("plane: %d of 800 triangles refined; %zu vertices, %zu triangles\n",
              mesh->refined_triangles, n, mesh->triangles.size() / 3);
  EXPECT_GT(mesh->triangles.size() / 3, 800u + 15 * mesh->refined_triangles);

  // Closed refinement: every edge in two triangles except the square's 80 border edges.
  std::map<std::pair<std::uint32_t, std::uint32_t>, int> edges;
  for (std::size_t t = 0; t < mesh->triangles.size(); t += 3)
    for (int k = 0; k < 3; ++k) {
      auto a = mesh->triangles[t + k], b = mesh->triangles[t + (k + 1) % 3];
      ++edges[{std::min(a, b), std::max(a, b)}];
    }
  int border = 0, other = 0;
  for (const auto& [e, count] : edges) {
    border += count == 1;
    other += count != 1 && count != 2;
  }
  EXPECT_EQ(border, 80);
  EXPECT_EQ(other, 0);

  double worst_inside = 0.0, worst_outside = 0.0, worst_uv = 0.0;
  int inside = 0, outside = 0;
  for (std::size_t v = 0; v < n; ++v) {
    const float* p = &mesh->positions[3 * v];
    const float* q = &mesh->undisplaced[3 * v];
    const double x = q[0], y = q[1];
    EXPECT_EQ(q[2], 0.0f);
    // Displaced along the plane's normal only.
    EXPECT_NEAR(p[0], q[0], 1e-6);
    EXPECT_NEAR(p[1], q[1], 1e-6);
    const bool in = x > 18 && x < 32 && y > 18 && y < 32;
    const bool out = x < 12 || x > 38 || y < 12 || y > 38;
    if (in) {
      ++inside;
      worst_inside =
          std::max(worst_inside, static_cast<double>(std::abs(p[2] - plane_height(x, y))));
    } else if (out) {
      ++outside;
      worst_outside = std::max(worst_outside, std::abs(static_cast<double>(p[2])));
    }
  }
  // UVs interpolated with the positions: u = x / 50, v = y / 50 at every corner.
  for (std::size_t c = 0; c < mesh->triangles.size(); ++c) {
    const std::uint32_t v = mesh->triangles[c], t = mesh->triangle_uvs[c];
    worst_uv = std::max({worst_uv, std::abs(mesh->uvs[2 * t] - mesh->undisplaced[3 * v] / 50.0),
                         std::abs(mesh->uvs[2 * t + 1] - mesh->undisplaced[3 * v + 1] / 50.0)});
  }
  std::printf("inside %d vertices: worst |z - h| %.4f mm; outside %d: worst |z| %.6f mm\n", inside,
              worst_inside, outside, worst_outside);
  EXPECT_GT(inside, 500);  // 14 mm square at 0.625 mm: 23 x 23
  EXPECT_LT(worst_inside, 0.01);
  EXPECT_GT(outside, 100);
  EXPECT_LT(worst_outside, 1e-6);
  EXPECT_LT(worst_uv, 1e-6);
}

TEST(DetailMesh, NoMapOrMismatchedLayoutIsAnError) {
  std::vector<float> v{0, 0, 0, 1, 0, 0, 0, 1, 0}, uv{0, 0, 1, 0, 0, 1};
  std::vector<std::uint32_t> t{0, 1, 2}, none;
  EXPECT_FALSE(subdivided_detail_mesh({v, t, uv, t, nullptr}));
  FloatImage map;
  map.resize(16, 16);
  auto r = subdivided_detail_mesh({v, t, uv, none, &map});
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("UV layout"), std::string::npos);
}

using test::UvLocator;

// The OBJ as written: positions, UVs and per vertex its first corner's UV.
struct ObjFile {
  std::vector<Eigen::Vector3d> v;
  std::vector<Eigen::Vector2d> vt;
  std::vector<int> uv_of;  // per v
  std::size_t faces = 0;
  std::string usemtl;
};
ObjFile read_obj_with_uvs(const fs::path& path) {
  ObjFile f;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream s(line);
    std::string tag;
    s >> tag;
    if (tag == "v") {
      Eigen::Vector3d p;
      s >> p.x() >> p.y() >> p.z();
      f.v.push_back(p);
      f.uv_of.push_back(-1);
    } else if (tag == "vt") {
      Eigen::Vector2d q;
      s >> q.x() >> q.y();
      f.vt.push_back(q);
    } else if (tag == "usemtl") {
      s >> f.usemtl;
    } else if (tag == "f") {
      ++f.faces;
      std::string corner;
      while (s >> corner) {
        const int vi = std::stoi(corner) - 1;
        const int ti = std::stoi(corner.substr(corner.find('/') + 1)) - 1;
        if (f.uv_of[static_cast<std::size_t>(vi)] < 0) f.uv_of[static_cast<std::size_t>(vi)] = ti;
      }
    }
  }
  return f;
}

// Through the OBJ export: a synthetic subject's pose 1 with a known height field on the forehead
// (0.3 + 0.25 sin(2 pi y / 7 mm), a 60 x 22 mm box above the brows) as its wrinkle detail.
TEST(DetailMesh, ObjExportCarriesTheHeightsAndAssimpLoadsIt) {
  auto model = load_face_model();
  ASSERT_TRUE(model) << model.error().message;
  SyntheticSubjectOptions so;
  so.seed = 3;
  auto subject = make_synthetic_subject(*model, so);
  ASSERT_TRUE(subject) << subject.error().message;
  ExportContent content = synthetic_content(*subject, 3, "facemodel.fbfm");
  use_face_model_uvs(content, *model);
  ASSERT_FALSE(content.uvs.empty());
  ASSERT_GE(content.poses.size(), 2u);
  const MeshData& pose = content.poses[1];
  // The box: above the brow landmarks (17-26), centred on them, on the front of the head.
  double brow_top = -1e9, cx = 0.0, front = -1e9;
  for (int l = 17; l <= 26; ++l) {
    const auto vi = model->landmark_vertices[static_cast<std::size_t>(l)];
    brow_top = std::max(brow_top, static_cast<double>(pose.positions[3 * vi + 1]));
    cx += pose.positions[3 * vi] / 10.0;
    front = std::max(front, static_cast<double>(pose.positions[3 * vi + 2]));
  }
  auto field = [&](const Eigen::Vector3d& p) {
    return std::abs(p.x() - cx) < 30 && p.y() > brow_top + 8 && p.y() < brow_top + 30 &&
                   p.z() > front - 40
               ? 0.3 + 0.25 * std::sin(2 * M_PI * p.y() / 7.0)
               : 0.0;
  };
  // Distance inside the box (negative outside); -1e9 off the front.
  auto depth_in_box = [&](const Eigen::Vector3d& p) {
    if (p.z() < front - 40) return -1e9;
    return std::min({30 - std::abs(p.x() - cx), p.y() - brow_top - 8, brow_top + 30 - p.y()});
  };
  auto map = make_texel_map(content.uvs.uvs, content.uvs.triangle_uvs, 1024, 512);
  ASSERT_TRUE(map);
  WrinkleDetailData detail;
  detail.width = 1024;
  detail.height = 512;
  detail.displacement_mm.assign(1024 * 512, 0.0f);
  for (std::size_t i = 0; i < map->triangle.size(); ++i)
    if (map->triangle[i] >= 0)
      detail.displacement_mm[i] = static_cast<float>(
          field(texel_point(*map, i, pose.triangles, pose.positions).cast<double>()));
  content.pose_details.assign(content.poses.size(), WrinkleDetailData{});
  content.pose_details[1] = detail;

  const fs::path dir = fs::temp_directory_path() / ("fb-detail-mesh-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  ExportRequest request;
  request.format = ExportFormat::kObj;
  request.out = dir / "obj";
  auto summary = export_content(content, request);
  ASSERT_TRUE(summary) << summary.error().message;
  const fs::path file = dir / "obj" / "poses" / "pose_1_detail.obj";
  ASSERT_TRUE(fs::exists(file));
  EXPECT_FALSE(fs::exists(dir / "obj" / "poses" / "pose_0_detail.obj"));  // no detail there
  const auto manifest = nlohmann::json::parse(std::ifstream(dir / "obj" / "manifest.json"));
  EXPECT_TRUE(manifest["details"].contains("detail_meshes"));
  std::ifstream mtl(dir / "obj" / "face.mtl");
  const std::string mtl_text((std::istreambuf_iterator<char>(mtl)), {});
  EXPECT_NE(mtl_text.find("newmtl skin_displaced"), std::string::npos) << mtl_text;

  const ObjFile obj = read_obj_with_uvs(file);
  EXPECT_EQ(obj.usemtl, "skin_displaced");
  std::printf("pose_1_detail.obj: %zu vertices, %zu triangles (the pose: %d, %d); %.1f MB\n",
              obj.v.size(), obj.faces, pose.vertex_count(), pose.triangle_count(),
              fs::file_size(file) / 1e6);
  const UvLocator locate(content.uvs.uvs, content.uvs.triangle_uvs);
  int inside = 0, outside = 0, unlocated = 0;
  double inside_err = 0.0, inside_worst = 0.0, outside_worst = 0.0;
  for (std::size_t v = 0; v < obj.v.size(); ++v) {
    const Eigen::Vector2d q = obj.vt[static_cast<std::size_t>(obj.uv_of[v])];
    const auto [t, b] = locate.find(q.x(), q.y());
    if (t < 0) {
      ++unlocated;
      continue;
    }
    // The undisplaced surface point with this UV: the pose's triangle (midpoint subdivision
    // keeps the surface).
    Eigen::Vector3d p0 = Eigen::Vector3d::Zero();
    for (int k = 0; k < 3; ++k) {
      const auto vi = pose.triangles[3 * static_cast<std::size_t>(t) + k];
      p0 += b[k] * Eigen::Vector3d(pose.positions[3 * vi], pose.positions[3 * vi + 1],
                                   pose.positions[3 * vi + 2]);
    }
    const double moved = (obj.v[v] - p0).norm();
    const double depth = depth_in_box(p0);
    if (depth > 3.0) {
      ++inside;
      const double err = std::abs(moved - field(p0));
      inside_err += err;
      inside_worst = std::max(inside_worst, err);
    } else if (depth < -3.0) {
      ++outside;
      outside_worst = std::max(outside_worst, moved);
    }
  }
  std::printf(
      "inside the box (> 3 mm from its edges): %d vertices, mean |moved - h| %.4f mm, worst "
      "%.4f; outside (> 3 mm): %d, worst moved %.5f mm; %d UVs not located\n",
      inside, inside_err / std::max(1, inside), inside_worst, outside, outside_worst, unlocated);
  EXPECT_LT(unlocated, static_cast<int>(obj.v.size() / 1000));  // zero-area UV triangles
  EXPECT_GT(inside, 1000);
  EXPECT_LT(inside_err / std::max(1, inside), 0.01);
  EXPECT_LT(inside_worst, 0.05);
  EXPECT_GT(outside, pose.vertex_count() / 2);
  EXPECT_LT(outside_worst, 0.05);

  // An outside reader: assimp loads it, with the material and no warnings.
  if (std::string(FB_ASSIMP_PATH).empty()) {
    fs::remove_all(dir);
    GTEST_SKIP() << "assimp (assimp-utils) is not installed";
  }
  const auto info = test::run_command(std::string(FB_ASSIMP_PATH) + " info " + file.string(),
                                      test::Stderr::kMerged);
  std::cout << info.out << "\n";
  EXPECT_EQ(info.exit_code, 0) << info.out;
  EXPECT_NE(info.out.find(std::to_string(obj.faces)), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("skin_displaced"), std::string::npos) << info.out;
  EXPECT_EQ(info.out.find("Warn"), std::string::npos) << info.out;
  fs::remove_all(dir);
}

}  // namespace
}  // namespace fb
