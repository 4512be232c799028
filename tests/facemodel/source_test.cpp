// The committed asset against its source: the ICT FaceKit OBJ/JSON files, read here with an
// independent, deliberately simple parser. Skipped when ../shared is not present.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include "algo/facemodel/face_model.hpp"
#include "tests/facemodel/test_util.hpp"

namespace fb {
namespace {

namespace fs = std::filesystem;
constexpr int kSkin = 11248;

#define FB_REQUIRE_SOURCE()                                                                    \
  const fs::path src = test::source_dir();                                                     \
  if (src.empty()) {                                                                           \
    GTEST_SKIP() << "ICT FaceKit source not found under " FB_SHARED_DIR                        \
                    "/facemodel/ict-facekit; the round trip against the OBJ files is skipped " \
                    "(the asset's own checks still run).";                                     \
  }

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// First `count` vertices of an OBJ, in centimetres as written.
std::vector<double> obj_vertices(const fs::path& p, int count) {
  const std::string text = slurp(p);
  std::vector<double> v;
  v.reserve(3 * count);
  const char* s = text.c_str();
  while (*s && static_cast<int>(v.size()) < 3 * count) {
    if (s[0] == 'v' && s[1] == ' ') {
      char* end = nullptr;
      const char* q = s + 2;
      for (int k = 0; k < 3; ++k) {
        v.push_back(std::strtod(q, &end));
        q = end;
      }
    }
    s = std::strchr(s, '\n');
    if (!s) break;
    ++s;
  }
  EXPECT_EQ(static_cast<int>(v.size()), 3 * count) << p;
  return v;
}

// max |model - 10 * obj| over the skin vertices, in mm.
double max_diff_mm(const std::vector<float>& model, const std::vector<double>& obj_cm) {
  double d = 0.0;
  for (std::size_t i = 0; i < model.size(); ++i) {
    d = std::max(d, std::abs(double{model[i]} - 10.0 * obj_cm[i]));
  }
  return d;
}

nlohmann::json vertex_indices(const fs::path& src) {
  return nlohmann::json::parse(slurp(src / "FaceXModel" / "vertex_indices.json"));
}

TEST(facemodel_source, NeutralMatchesObj) {
  FB_REQUIRE_SOURCE();
  const FaceModel& m = test::asset_model();
  const auto obj = obj_vertices(src / "FaceXModel" / "generic_neutral_mesh.obj", kSkin);
  std::vector<float> out(3 * kSkin);
  m.evaluate({}, {}, out);
  const double d = max_diff_mm(out, obj);
  std::printf("neutral: max |asset - OBJ*10| = %.3g mm\n", d);
  EXPECT_LT(d, 1e-3);
}

TEST(facemodel_source, EveryIdentityModeMatchesItsObj) {
  FB_REQUIRE_SOURCE();
  const FaceModel& m = test::asset_model();
  ASSERT_EQ(m.identity_count, 100);
  std::vector<float> c(m.identity_count, 0.0f), out(3 * kSkin);
  double worst = 0.0;
  for (int k = 0; k < m.identity_count; ++k) {
    char name[32];
    std::snprintf(name, sizeof name, "identity%03d.obj", k);
    std::fill(c.begin(), c.end(), 0.0f);
    c[k] = 1.0f;
    m.evaluate(c, {}, out);
    const double d = max_diff_mm(out, obj_vertices(src / "FaceXModel" / name, kSkin));
    worst = std::max(worst, d);
    EXPECT_LT(d, 1e-3) << name;
  }
  std::printf("identity modes (c_k = 1, 100 files): max |asset - OBJ*10| = %.3g mm\n", worst);
}

TEST(facemodel_source, EveryExpressionMatchesItsObjInOrder) {
  FB_REQUIRE_SOURCE();
  const FaceModel& m = test::asset_model();
  const auto json = vertex_indices(src);
  std::vector<std::string> names = json["expressions"].get<std::vector<std::string>>();
  ASSERT_EQ(names.size(), 53u);
  EXPECT_EQ(m.fitting_expression_count, 53);
  for (const char* extra : {"cheekRaiser_L", "cheekRaiser_R", "PupilDilate_L", "PupilDilate_R"}) {
    names.emplace_back(extra);
  }
  ASSERT_EQ(m.expression_names, names);
  std::vector<float> w(m.expression_count, 0.0f), out(3 * kSkin);
  double worst = 0.0;
  for (int j = 0; j < m.expression_count; ++j) {
    std::fill(w.begin(), w.end(), 0.0f);
    w[j] = 1.0f;
    m.evaluate({}, w, out);
    const double d =
        max_diff_mm(out, obj_vertices(src / "FaceXModel" / (names[j] + ".obj"), kSkin));
    worst = std::max(worst, d);
    EXPECT_LT(d, 1e-3) << names[j];
    EXPECT_EQ(m.expression_index(names[j]), j);
  }
  std::printf("expressions (w_j = 1, 57 files): max |asset - OBJ*10| = %.3g mm\n", worst);
}

TEST(facemodel_source, TrianglesCoverTheSkinPolygons) {
  FB_REQUIRE_SOURCE();
  const FaceModel& m = test::asset_model();
  // Polygons 0-11143 of the neutral OBJ, as vertex sets.
  std::istringstream in(slurp(src / "FaceXModel" / "generic_neutral_mesh.obj"));
  std::vector<std::vector<std::uint32_t>> polys;
  std::string line;
  while (polys.size() < 11144 && std::getline(in, line)) {
    if (line.rfind("f ", 0) != 0) continue;
    std::istringstream ls(line.substr(2));
    std::string tok;
    std::vector<std::uint32_t> p;
    while (ls >> tok) p.push_back(static_cast<std::uint32_t>(std::stoul(tok)) - 1);
    polys.push_back(p);
  }
  ASSERT_EQ(polys.size(), 11144u);
  std::size_t expected = 0;
  for (const auto& p : polys) expected += p.size() - 2;
  std::printf("triangles: %d (from %zu polygons)\n", m.triangle_count(), polys.size());
  ASSERT_EQ(static_cast<std::size_t>(m.triangle_count()), expected);
  // Quads are split into two consecutive triangles whose vertices are the quad's vertices
  // and that keep its orientation (each triangle is a cyclic subsequence of the polygon).
  std::size_t t = 0;
  for (const auto& p : polys) {
    std::set<std::uint32_t> covered;
    for (std::size_t k = 0; k + 2 < p.size(); ++k, ++t) {
      const std::uint32_t* tri = &m.triangles[3 * t];
      const auto a = std::find(p.begin(), p.end(), tri[0]);
      ASSERT_NE(a, p.end());
      const std::size_t ia = static_cast<std::size_t>(a - p.begin());
      const std::size_t ib =
          static_cast<std::size_t>(std::find(p.begin(), p.end(), tri[1]) - p.begin());
      const std::size_t ic =
          static_cast<std::size_t>(std::find(p.begin(), p.end(), tri[2]) - p.begin());
      ASSERT_LT(ib, p.size());
      ASSERT_LT(ic, p.size());
      const std::size_t n = p.size();
      EXPECT_LT((ib + n - ia) % n, (ic + n - ia) % n) << "triangle " << t << " flips its winding";
      covered.insert({tri[0], tri[1], tri[2]});
    }
    EXPECT_EQ(covered.size(), p.size());
  }
  // Triangles face outward: over the face region the area-weighted normal points to +Z.
  double nz = 0.0;
  const auto& v = m.neutral;
  for (int i = 0; i < m.triangle_count(); ++i) {
    const std::uint32_t a = m.triangles[3 * i], b = m.triangles[3 * i + 1],
                        c = m.triangles[3 * i + 2];
    if (a >= 9409 || b >= 9409 || c >= 9409) continue;
    const double ux = v[3 * b] - v[3 * a], uy = v[3 * b + 1] - v[3 * a + 1];
    const double wx = v[3 * c] - v[3 * a], wy = v[3 * c + 1] - v[3 * a + 1];
    nz += ux * wy - uy * wx;
  }
  EXPECT_GT(nz, 0.0) << "face triangles are wound clockwise as seen from the front";
}

// The asset's UV layout is the source's: every triangle corner carries the `vt` its polygon
// corner has in generic_neutral_mesh.obj (seam vertices keep one UV per side).
TEST(facemodel_source, UvsAreTheSourceLayout) {
  FB_REQUIRE_SOURCE();
  const FaceModel& m = test::asset_model();
  ASSERT_FALSE(m.uvs.empty()) << "data/facemodel.fbfm has no UVs: re-run the converter";
  ASSERT_EQ(m.triangle_uvs.size(), m.triangles.size());
  std::istringstream in(slurp(src / "FaceXModel" / "generic_neutral_mesh.obj"));
  std::vector<double> vt;
  // (vertex, u, v) triples the skin polygons use.
  std::set<std::tuple<std::uint32_t, float, float>> corners;
  std::string line;
  int polygons = 0;
  while (polygons < 11144 && std::getline(in, line)) {
    if (line.rfind("vt ", 0) == 0) {
      std::istringstream ls(line.substr(3));
      double u = 0, v = 0;
      ls >> u >> v;
      vt.push_back(u);
      vt.push_back(v);
    } else if (line.rfind("f ", 0) == 0) {
      ++polygons;
      std::istringstream ls(line.substr(2));
      std::string tok;
      while (ls >> tok) {
        const auto slash = tok.find('/');
        ASSERT_NE(slash, std::string::npos) << "polygon " << polygons << " has no vt";
        const auto vertex = static_cast<std::uint32_t>(std::stoul(tok)) - 1;
        const auto uv = std::stoul(tok.substr(slash + 1)) - 1;
        ASSERT_LT(2 * uv + 1, vt.size());
        corners.insert(
            {vertex, static_cast<float>(vt[2 * uv]), static_cast<float>(vt[2 * uv + 1])});
      }
    }
  }
  std::set<std::pair<std::uint32_t, std::uint32_t>> pairs;
  for (std::size_t c = 0; c < m.triangles.size(); ++c) {
    const std::uint32_t uv = m.triangle_uvs[c];
    ASSERT_LT(2 * uv + 1, m.uvs.size());
    EXPECT_TRUE(corners.count({m.triangles[c], m.uvs[2 * uv], m.uvs[2 * uv + 1]}))
        << "corner " << c << " (vertex " << m.triangles[c] << ") has a UV its polygon lacks";
    pairs.insert({m.triangles[c], uv});
  }
  std::printf(
      "UVs: %zu for %d vertices; %zu (vertex, UV) pairs in the source's skin corners, "
      "%zu in the asset\n",
      m.uvs.size() / 2, m.vertex_count, corners.size(), pairs.size());
  EXPECT_EQ(pairs.size(), corners.size());
  EXPECT_GT(m.uvs.size() / 2, static_cast<std::size_t>(m.vertex_count));  // seams are split
}

TEST(facemodel_source, VertexListsMatchTheJsonFiles) {
  FB_REQUIRE_SOURCE();
  const FaceModel& m = test::asset_model();
  const auto json = vertex_indices(src);
  const auto lmk = json["idx_to_landmark_verts"].get<std::vector<std::uint32_t>>();
  ASSERT_EQ(lmk.size(), 68u);
  EXPECT_TRUE(std::equal(lmk.begin(), lmk.end(), m.landmark_vertices.begin()));
  EXPECT_EQ(m.rigid_landmarks, json["idx_to_rigid_landmark_idx"].get<std::vector<std::uint32_t>>());
  EXPECT_EQ(m.fitting_vertices, json["idx_to_fitting_verts"].get<std::vector<std::uint32_t>>());
  std::vector<std::uint32_t> rigid;
  for (const auto i : json["idx_to_rigid_verts"].get<std::vector<std::uint32_t>>()) {
    if (i < kSkin) rigid.push_back(i);
  }
  EXPECT_EQ(m.rigid_vertices, rigid);
  EXPECT_FALSE(rigid.empty());

  const auto jaw = nlohmann::json::parse(slurp(src / "jawline_indices.json"));
  EXPECT_EQ(m.right_jawline, jaw["right_jawline_for_lmk_0_7"].get<std::vector<std::uint32_t>>());
  EXPECT_EQ(m.left_jawline, jaw["left_jawline_for_lmk_9_16"].get<std::vector<std::uint32_t>>());
  EXPECT_EQ(m.right_extended_jawline,
            jaw["right_extended_jawline"].get<std::vector<std::uint32_t>>());
  EXPECT_EQ(m.left_extended_jawline,
            jaw["left_extended_jawline"].get<std::vector<std::uint32_t>>());
  EXPECT_EQ(m.face_vertex_count, 9409);
}

}  // namespace
}  // namespace fb
