// Section V: correspondence between meshes of different topology, on the face model remeshed
// (sim/subject/remesh.hpp) so that every target vertex's true place on the source is known.
#include <gtest/gtest.h>

#include <iostream>
#include <set>

#include "algo/transfer/correspondence.hpp"
#include "algo/transfer/expression_set.hpp"
#include "sim/subject/remesh.hpp"
#include "tests/common/test_face_model.hpp"

namespace fb {
namespace {

TEST(Delaunay, GridIsTriangulatedCounterClockwise) {
  std::vector<Eigen::Vector2d> pts;
  for (int y = 0; y < 5; ++y)
    for (int x = 0; x < 6; ++x) pts.emplace_back(x + 0.01 * y, y * 1.3);
  const auto tris = delaunay(pts);
  EXPECT_EQ(tris.size(), 3u * 2 * 5 * 4);  // 2 (nx - 1)(ny - 1) triangles
  for (std::size_t t = 0; t < tris.size(); t += 3) {
    const Eigen::Vector2d a = pts[tris[t]], b = pts[tris[t + 1]], c = pts[tris[t + 2]];
    EXPECT_GT((b - a).x() * (c - a).y() - (b - a).y() * (c - a).x(), 0);
  }
}

Points landmarks(const FaceModel& m, const Points& p) {
  Points out(68, 3);
  for (int l = 0; l < 68; ++l) out.row(l) = p.row(m.landmark_vertices[static_cast<std::size_t>(l)]);
  return out;
}

Points identity_face(const std::vector<float>& c) {
  const FaceModel& m = test::face_model();
  std::vector<float> out(m.neutral.size());
  m.evaluate(c, {}, out);
  return points_from_floats(out);
}

std::vector<std::pair<const char*, Remesh>> remeshes() {
  const FaceModel& m = test::face_model();
  const std::vector<std::uint32_t> keep(m.landmark_vertices.begin(), m.landmark_vertices.end());
  std::vector<std::pair<const char*, Remesh>> out;
  out.emplace_back("decimated", decimate(m.triangles, points_from_floats(m.neutral), 0.5, keep));
  out.emplace_back("flipped", flip_quad_diagonals(m.triangles, m.vertex_count));
  out.emplace_back("split",
                   split_at_centroids(m.triangles, m.vertex_count, m.face_vertex_count, 19000));
  return out;
}

TEST(Remesh, MeshesAreValidAndOfAnotherTopology) {
  const FaceModel& m = test::face_model();
  ASSERT_GT(m.vertex_count, 0);
  for (const auto& [name, r] : remeshes()) {
    auto faces = faces_of(r.vertex_count(), r.triangles, 3);
    ASSERT_TRUE(faces) << name << ": " << faces.error().message;
    EXPECT_NE(r.triangles, m.triangles) << name;
    EXPECT_EQ(tent_topology(*faces).component_count, 1) << name;
  }
  const auto all = remeshes();
  EXPECT_LT(all[0].second.vertex_count(), m.vertex_count * 0.55);
  EXPECT_EQ(all[2].second.vertex_count(), 19000);
}

// The same face remeshed: every target vertex lies on the source, so its source point must be
// its true position (the 3D search within the warp's neighbourhood finds it exactly).
TEST(Correspondence, SameFaceRemeshedFindsTheTruePlaces) {
  const FaceModel& m = test::face_model();
  const Points face = identity_face({0.5f, 1.0f, -0.3f});
  for (const auto& [name, r] : remeshes()) {
    const Points target = r.apply(face);
    auto c = find_correspondence(face, m.triangles, landmarks(m, face), target, landmarks(m, face));
    ASSERT_TRUE(c) << name;
    EXPECT_EQ(c->unmatched, 0) << name;
    double worst = 0;
    for (int v = 0; v < target.rows(); ++v) {
      const SurfacePoint& p = c->points[static_cast<std::size_t>(v)];
      const Eigen::RowVector3d x = p.weights[0] * face.row(p.corners[0]) +
                                   p.weights[1] * face.row(p.corners[1]) +
                                   p.weights[2] * face.row(p.corners[2]);
      worst = std::max(worst, (x - target.row(v)).norm());
    }
    EXPECT_LT(worst, 1e-6) << name;  // mm
  }
}

// Subject A's expressions on the model mesh onto subject B remeshed, against B's truth (the same
// expression delta, remeshed): mean error over the vertices the truth moves.
double cross_topology_error(const Remesh& r, CrossTopologyMethod method) {
  const FaceModel& m = test::face_model();
  const Points a = identity_face({1.0f, -0.5f, 0.8f, 0.3f});
  const Points b = identity_face({-1.2f, 0.7f, 0.0f, 1.0f, -0.5f});
  const auto topology = tent_topology(*faces_of(m.vertex_count, m.triangles, 3));
  std::vector<Points> expr;
  std::vector<int> shapes;
  for (const char* n : {"jawOpen", "eyeBlink_L", "mouthSmile_R", "browInnerUp_L"})
    shapes.push_back(m.expression_index(n));
  for (int j : shapes) expr.push_back(a + points_from_floats(m.expression_shape(j)));
  const auto tt = tent_topology(*faces_of(r.vertex_count(), r.triangles, 3));
  auto out = transfer_expression_set_across(topology, a, expr, landmarks(m, a), tt, r.apply(b),
                                            landmarks(m, b), method);
  EXPECT_TRUE(out) << out.error().message;
  if (!out) return 1e9;
  double sum = 0;
  int n = 0;
  for (std::size_t i = 0; i < shapes.size(); ++i) {
    const Points truth = r.apply(b + points_from_floats(m.expression_shape(shapes[i])));
    const Points neutral = r.apply(b);
    for (int v = 0; v < truth.rows(); ++v) {
      if ((truth.row(v) - neutral.row(v)).norm() < 0.1) continue;
      sum += (out->expressions[i].row(v) - truth.row(v)).norm();
      ++n;
    }
  }
  return sum / n;
}

// The default (the target resampled at the source's vertices) on every remeshed target.
TEST(Correspondence, CrossTopologyTransferMatchesTheTruth) {
  for (const auto& [name, r] : remeshes()) {
    const double e = cross_topology_error(r, CrossTopologyMethod::kResample);
    std::cout << name << ": " << e << " mm\n";
    EXPECT_LT(e, 1.0) << name;  // mm
  }
}

// On triangles split at their centroids (valence-3 vertices in the plane of their ring) the
// solve on the target's own tents is far worse than the resampled one (docs/transfer.md).
TEST(Correspondence, ResamplingBeatsTargetTentsOnASplitMesh) {
  const auto all = remeshes();
  const Remesh& split = all[2].second;
  const double resample = cross_topology_error(split, CrossTopologyMethod::kResample);
  const double tents = cross_topology_error(split, CrossTopologyMethod::kTargetTents);
  std::cout << "split: resample " << resample << " mm, target tents " << tents << " mm\n";
  EXPECT_LT(resample, 0.7 * tents);
}

}  // namespace
}  // namespace fb
