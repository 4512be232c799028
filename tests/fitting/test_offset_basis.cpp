// The neutral fit's offsets along the normal (algo/fitting/offset_basis.hpp): the basis itself,
// and a face with a bump the identity modes cannot hold.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <vector>

#include "algo/fitting/face_fit.hpp"
#include "algo/fitting/offset_basis.hpp"
#include "tests/common/test_face_model.hpp"
#include "tests/fitting/fit_scene.hpp"

namespace fb {
namespace {

Eigen::Vector3f at(const std::vector<float>& mesh, std::size_t v) {
  return {mesh[3 * v], mesh[3 * v + 1], mesh[3 * v + 2]};
}

TEST(OffsetBasis, BumpsCoverTheFaceButNotTheEyesAndMouth) {
  const FaceModel& model = test::face_model();
  const std::vector<float> mean = face({});
  const OffsetBasis basis = make_offset_basis(model, mean, model.fitting_vertices);
  std::printf("%d bumps\n", basis.count);
  // The face region is about 150 x 200 mm: some tens of 30 mm bumps.
  EXPECT_GE(basis.count, 8);
  EXPECT_LE(basis.count, 80);
  // The eyes' and the mouth's landmark vertices do not move; the cheeks and the forehead do.
  for (std::size_t l = 36; l < 68; ++l)
    EXPECT_TRUE(basis.of(model.landmark_vertices[l]).empty()) << "landmark " << l;
  std::size_t moved = 0;
  for (std::uint32_t v : model.fitting_vertices) moved += !basis.of(v).empty();
  EXPECT_GT(moved, model.fitting_vertices.size() * 8 / 10);
  // One bump at 2 mm moves a vertex along its normal by 2 mm x its weight there.
  std::vector<double> amplitude(static_cast<std::size_t>(basis.count), 0.0);
  amplitude[0] = 2.0;
  std::vector<float> bent = mean;
  add_offsets(basis, amplitude, bent);
  double largest = 0;
  for (std::uint32_t v : model.fitting_vertices) {
    const Eigen::Vector3f d = at(bent, v) - at(mean, v);
    float w = 0;
    for (const auto& e : basis.of(v)) w += e.bump == 0 ? e.weight : 0.0f;
    ASSERT_NEAR(d.norm(), 2.0 * w, 1e-4);
    if (d.norm() > 1e-3) {
      ASSERT_GT(d.normalized().dot(basis.normal[v]), 0.999f);
    }
    largest = std::max(largest, static_cast<double>(d.norm()));
  }
  EXPECT_GT(largest, 1.0);  // at its centre, less where the features hold it
}

// A face the 100 modes cannot hold: a broad bump (30 mm, 3 mm high) on one cheek, along the
// normal. Without offsets the modes that fit it slide the face along itself; with them the
// PCA step's mesh is nearer the truth, and so is the refined one.
TEST(OffsetBasis, ABumpTheModesCannotHoldBendsTheSurfaceInstead) {
  const FaceModel& model = test::face_model();
  std::vector<float> truth = face(random_identity(5));
  const OffsetBasis normals = make_offset_basis(model, truth, model.fitting_vertices);
  const Eigen::Vector3f cheek =
      at(truth, model.landmark_vertices[3]) * 0.6f + at(truth, model.landmark_vertices[31]) * 0.4f;
  for (std::size_t v = 0; v < static_cast<std::size_t>(model.vertex_count); ++v) {
    const float d2 = (at(truth, v) - cheek).squaredNorm();
    const Eigen::Vector3f d = 3.0f * std::exp(-d2 / (2 * 30.0f * 30.0f)) * normals.normal[v];
    for (int a = 0; a < 3; ++a) truth[3 * v + a] += d[a];
  }
  const RigidPose pose = truth_pose(truth);
  const FitTarget target = render_target(truth, pose, 1.0);
  NeutralFitOptions off;
  off.offset_amplitude_mm = 0;
  auto with = fit_neutral(model, target);
  auto without = fit_neutral(model, target, off);
  ASSERT_TRUE(with.ok()) << with.error().message;
  ASSERT_TRUE(without.ok()) << without.error().message;
  auto error = [&](const FitResult& f, bool refined) {
    return mean_vertex_distance(refined ? f.vertices : f.initial_vertices, f.camera_from_model,
                                truth, pose, model.fitting_vertices);
  };
  std::printf("bumped face, PCA step / refined: %.3f / %.3f mm with offsets, %.3f / %.3f without\n",
              error(*with, false), error(*with, true), error(*without, false),
              error(*without, true));
  // Measured 0.536 / 0.535 with, 0.639 / 0.631 without.
  EXPECT_LT(error(*with, false), 0.9 * error(*without, false));
  EXPECT_LT(error(*with, true), 0.9 * error(*without, true));
}

}  // namespace
}  // namespace fb
