// Feature points for a mesh without landmarks (issue 39 item 2): the face model remeshed (so
// the true landmark positions are known), drawn frontally, dlib's 68 points on the picture
// carried back onto the surface; then the cross-topology transfer with the found points.
#include <gtest/gtest.h>

#include <fstream>
#include <iostream>
#include <optional>

#include "algo/landmarks/landmark_detector.hpp"
#include "algo/transfer/expression_set.hpp"
#include "algo/transfer/mesh_features.hpp"
#include "sim/subject/remesh.hpp"
#include "tests/common/test_face_model.hpp"

namespace fb {
namespace {

constexpr const char* kPredictor = "/usr/share/dlib/shape_predictor_68_face_landmarks.dat";

LandmarkDetector& detector() {
  static std::optional<LandmarkDetector> d = [] {
    std::ifstream in(kPredictor, std::ios::binary);
    auto made = LandmarkDetector::create(in);
    EXPECT_TRUE(made.ok()) << (made.ok() ? "" : made.error().message);
    return made ? std::optional<LandmarkDetector>(std::move(*made)) : std::nullopt;
  }();
  return *d;
}

Points identity_face(const std::vector<float>& c) {
  const FaceModel& m = test::face_model();
  std::vector<float> out(m.neutral.size());
  m.evaluate(c, {}, out);
  return points_from_floats(out);
}

Points landmarks(const Points& p) {
  const FaceModel& m = test::face_model();
  Points out(68, 3);
  for (int l = 0; l < 68; ++l) out.row(l) = p.row(m.landmark_vertices[static_cast<std::size_t>(l)]);
  return out;
}

// dlib's 68 points on the frontal render, on the surface.
Result<Points> found_features(const Points& p, std::span<const std::uint32_t> triangles) {
  const FrontalRender r = render_frontal(p, triangles);
  detector().reset_tracking();
  auto found = detector().detect(r.image);
  if (!found) return found.failure();
  return back_project(r, p, triangles, found->points);
}

Remesh split_mesh() {
  const FaceModel& m = test::face_model();
  return split_at_centroids(m.triangles, m.vertex_count, m.face_vertex_count, 19000);
}

TEST(MeshFeatures, BackProjectionHitsTheRenderedSurface) {
  const FaceModel& m = test::face_model();
  const Points face = identity_face({0.5f, 1.0f, -0.3f});
  const FrontalRender r = render_frontal(face, m.triangles);
  // The landmark vertices projected by the render's camera come back onto themselves.
  const Points truth = landmarks(face);
  const Eigen::RowVector3d nose = truth.row(30);
  std::vector<Eigen::Vector2d> px;
  const double zmax = face.col(2).maxCoeff();
  Eigen::RowVector3d lo = Eigen::RowVector3d::Constant(1e300), hi = -lo;
  for (Eigen::Index v = 0; v < face.rows(); ++v)
    if (face(v, 2) >= zmax - 90) lo = lo.cwiseMin(face.row(v)), hi = hi.cwiseMax(face.row(v));
  const Eigen::RowVector3d c(0.5 * (lo.x() + hi.x()), 0.5 * (lo.y() + hi.y()), zmax);
  for (int l : {30, 36, 45, 48, 54, 8}) {
    const Eigen::RowVector3d d = truth.row(l) - c;
    px.push_back(r.camera.project(Eigen::Vector3d(d.x(), -d.y(), 1500 - d.z())));
  }
  auto back = back_project(r, face, m.triangles, px);
  ASSERT_TRUE(back) << back.error().message;
  int k = 0;
  for (int l : {30, 36, 45, 48, 54, 8}) {
    // mm: a pixel is 0.37 mm here; the eye corners lie in a fold that the frontal ray meets on
    // the lid first (1.7 mm away), everything else within a pixel's footprint.
    const bool fold = l == 36 || l == 45;
    EXPECT_LT((back->row(k) - truth.row(l)).norm(), fold ? 2.5 : 1.0) << l;
    ++k;
  }
  EXPECT_GT(nose.z(), 0);
}

// dlib on the render of a remeshed face: mean distance of the found points to the model's
// landmark vertices (the truth), and the transfer with found points on both faces.
TEST(MeshFeatures, FoundPointsDriveTheCrossTopologyTransfer) {
  const FaceModel& m = test::face_model();
  const Points a = identity_face({1.0f, -0.5f, 0.8f, 0.3f});
  const Points b = identity_face({-1.2f, 0.7f, 0.0f, 1.0f, -0.5f});
  const Remesh r = split_mesh();
  const Points target = r.apply(b);
  auto target_found = found_features(target, r.triangles);
  ASSERT_TRUE(target_found) << target_found.error().message;
  auto source_found = found_features(a, m.triangles);
  ASSERT_TRUE(source_found) << source_found.error().message;
  const Points truth = landmarks(b);
  double sum = 0, inner = 0;
  for (int l = 0; l < 68; ++l) {
    const double d = (target_found->row(l) - truth.row(l)).norm();
    sum += d;
    if (l >= 17) inner += d;
  }
  std::cout << "found feature points: mean " << sum / 68 << " mm, without the contour "
            << inner / 51 << " mm\n";
  const auto topology = tent_topology(*faces_of(m.vertex_count, m.triangles, 3));
  const auto tt = tent_topology(*faces_of(r.vertex_count(), r.triangles, 3));
  std::vector<Points> expr;
  std::vector<int> shapes;
  for (const char* n : {"jawOpen", "eyeBlink_L", "mouthSmile_R", "browInnerUp_L"})
    shapes.push_back(m.expression_index(n));
  for (int j : shapes) expr.push_back(a + points_from_floats(m.expression_shape(j)));
  auto error_with = [&](const Points& source_features, const Points& target_features) {
    auto out = transfer_expression_set_across(topology, a, expr, source_features, tt, target,
                                              target_features);
    EXPECT_TRUE(out) << out.error().message;
    if (!out) return 1e9;
    double s = 0;
    int n = 0;
    for (std::size_t i = 0; i < shapes.size(); ++i) {
      const Points t = r.apply(b + points_from_floats(m.expression_shape(shapes[i])));
      for (int v = 0; v < t.rows(); ++v) {
        if ((t.row(v) - target.row(v)).norm() < 0.1) continue;
        s += (out->expressions[i].row(v) - t.row(v)).norm();
        ++n;
      }
    }
    return s / n;
  };
  const double given = error_with(landmarks(a), landmarks(b));
  const double found_both = error_with(*source_found, *target_found);
  const double found_target = error_with(landmarks(a), *target_found);
  std::cout << "cross-topology error: given " << given << " mm, found on both " << found_both
            << " mm, found on the target only " << found_target << " mm\n";
  // Measured: 5.2 mm (3.4 without the contour, whose points dlib puts on the silhouette, not
  // on the model's landmark vertices); the transfer 0.99 mm with found points on both faces
  // (0.81 given): within the 1.0 mm.
  EXPECT_LT(sum / 68, 7.0);
  EXPECT_LT(inner / 51, 5.0);
  EXPECT_LT(found_both, 1.0);
  EXPECT_LT(found_target, 1.0);
}

}  // namespace
}  // namespace fb
