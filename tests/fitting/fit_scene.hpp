// Test scenes for the fit: a face of the face model rendered as a Kinect's depth with its 68
// landmarks (test_fitting, test_offset_basis).
#pragma once

#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "algo/fitting/face_fit.hpp"
#include "algo/render/rasterizer.hpp"
#include "tests/common/test_face_model.hpp"

namespace fb {

inline PinholeIntrinsics kinect() {
  PinholeIntrinsics k;
  k.fx = k.fy = 575.8;
  k.cx = 320;
  k.cy = 240;
  return k;
}

// Face towards the camera (180 deg about x), a small yaw, landmark centroid at 700 mm.
inline RigidPose truth_pose(const std::vector<float>& mesh, double yaw_deg = 8.0) {
  RigidPose p;
  p.rotation =
      Eigen::Quaterniond(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX())) *
      Eigen::Quaterniond(Eigen::AngleAxisd(yaw_deg * M_PI / 180, Eigen::Vector3d::UnitY()));
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (auto v : test::face_model().landmark_vertices)
    c += Eigen::Vector3d(mesh[3 * v], mesh[3 * v + 1], mesh[3 * v + 2]);
  c /= 68;
  p.translation = Eigen::Vector3d(0, 0, 700) - p.rotation * c;
  return p;
}

inline std::vector<float> face(const std::vector<float>& identity,
                               const std::vector<float>& weights = {}) {
  std::vector<float> m(static_cast<std::size_t>(test::face_model().vertex_count) * 3);
  test::face_model().evaluate(identity, weights, m);
  return m;
}

inline std::vector<float> random_identity(unsigned seed, float scale = 1.0f) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> n(0, scale);
  std::vector<float> c(static_cast<std::size_t>(test::face_model().identity_count));
  for (auto& x : c) x = n(rng);
  return c;
}

inline FitTarget render_target(const std::vector<float>& mesh, const RigidPose& pose,
                               double landmark_noise_px = 0.0, unsigned seed = 1) {
  FitTarget t;
  t.intrinsics = kinect();
  std::vector<Eigen::Vector3f> v(static_cast<std::size_t>(test::face_model().vertex_count));
  for (int i = 0; i < test::face_model().vertex_count; ++i)
    v[i] = pose.apply({mesh[3 * i], mesh[3 * i + 1], mesh[3 * i + 2]}).cast<float>();
  RasterBuffers rb;
  rb.reset(640, 480);
  EXPECT_TRUE(rasterize(t.intrinsics, v, test::face_model().triangles, RasterOptions{}, rb).ok());
  t.depth_mm.resize(640, 480);
  for (int y = 0; y < 480; ++y)
    for (int x = 0; x < 640; ++x)
      t.depth_mm.at(x, y) = rb.covered(x, y) ? rb.depth[rb.index(x, y)] : 0.0f;
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0, landmark_noise_px);
  for (int l = 0; l < 68; ++l) {
    const Eigen::Vector3d p = v[test::face_model().landmark_vertices[l]].cast<double>();
    FitLandmark& lm = t.landmarks[l];
    lm.valid = true;
    lm.pixel = t.intrinsics.project(p);
    if (landmark_noise_px > 0) lm.pixel += Eigen::Vector2d(n(rng), n(rng));
    if (!is_contour_landmark(l)) lm.point = lift_with_depth(t, lm.pixel, 1);
  }
  EXPECT_TRUE(prepare_fit_target(t).ok());
  return t;
}

}  // namespace fb
