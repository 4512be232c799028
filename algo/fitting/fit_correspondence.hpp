// Where a fitted vertex meets the target (internal to algo/fitting): projective depth
// correspondences, the mesh's own visibility, the landmarks' vertices. Shared by the neutral
// fit, the refinement and the expression amplitude fit; the per-vertex test is inline because
// every Gauss-Newton step calls it thousands of times.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "algo/fitting/face_fit.hpp"
#include "algo/fitting/mesh_ops.hpp"

namespace fb::fitting_detail {

inline Points posed(const Points& v, const Eigen::Matrix3d& r, const Eigen::Vector3d& t) {
  Points x = v * r.transpose();
  x.rowwise() += t.transpose();
  return x;
}

// A hair or beard sample whose depth normal is within 30 deg of the face's lies along the face
// (hair on a forehead). Elsewhere it is a bound only: the hairline's ramp, or a collar in front
// of the neck, would pull the face down along itself (docs/tuning.md).
inline constexpr double kAlongFaceCos = 0.866;

// Projective correspondence: the depth sample under the vertex's projection, its normal, and
// gates on distance and on the angle between the vertex normal and the depth normal.
struct Correspondence {
  Eigen::Vector3d q;        // depth point
  Eigen::Vector3d n;        // unit, towards the camera
  double confidence = 1.0;  // the target's, at the sample
  double skin = 1.0;        // the target's skin weight at the sample
  // Hair and beard samples: whether the depth's surface runs along the face's here (hair lying
  // on it), so that a face behind it may be pulled towards it.
  bool along_face = true;
};

inline bool correspond(const FitTarget& t, const Eigen::Vector3d& x, const Eigen::Vector3d& vn,
                       double gate_mm, double cos_min, Correspondence& c) {
  if (x.z() <= 1.0) return false;
  const Eigen::Vector2d uv = t.intrinsics.project(x);
  const int px = static_cast<int>(std::lround(uv.x())), py = static_cast<int>(std::lround(uv.y()));
  if (!t.depth_mm.contains(px, py)) return false;
  const float d = t.depth_mm.at(px, py);
  if (!(d > 0.0f)) return false;
  const Eigen::Vector3f nf = t.normals.at(px, py);
  if (nf.squaredNorm() < 0.5f) return false;
  c.n = nf.cast<double>();
  c.q = t.intrinsics.unproject(px, py, d);
  c.confidence = t.confidence.empty() ? 1.0 : static_cast<double>(t.confidence.at(px, py));
  c.skin = t.skin.empty() ? 1.0 : static_cast<double>(t.skin.at(px, py));
  if (vn.squaredNorm() > 0.5 && vn.dot(c.n) < cos_min) return false;
  const double plane = c.n.dot(x - c.q);
  if (std::abs(plane) > gate_mm || (x - c.q).norm() > 2.0 * gate_mm + 3.0) return false;
  // On hair and a beard the depth's normal is the hair's: noisy, and at the hairline a ramp
  // facing down the forehead, so a pull along it slides the face along its own surface
  // (docs/tuning.md). The bound holds along the face's normal instead; the gate above stays on
  // the depth's own plane.
  if (c.skin < 0.5 && vn.squaredNorm() > 0.5) {
    c.along_face = vn.normalized().dot(c.n) >= kAlongFaceCos;
    c.n = vn.normalized();
  }
  return true;
}

// Hair and a beard are measured in front of the skin: their depth only says the face is not in
// front of it. A vertex behind such a sample (or on it) takes nothing from it; one in front of
// it is pushed back as by skin.
inline bool behind_hair(const Correspondence& c, const Eigen::Vector3d& x) {
  return c.skin < 0.5 && c.n.dot(x - c.q) <= 0.0;
}

// Direction of the viewing ray through a pixel (z = 1).
inline Eigen::Vector3d ray(const PinholeIntrinsics& k, const Eigen::Vector2d& px) {
  return {(px.x() - k.cx) / k.fx, (px.y() - k.cy) / k.fy, 1.0};
}

// Vertices that the mesh itself does not hide from the camera: rasterise the posed mesh and
// keep vertices within `slack_mm` of the z-buffer at their pixel. Hidden vertices (behind the
// nose, under the jaw) would otherwise match the occluder's depth.
std::vector<char> visible_vertices(const FitTarget& t, const Points& x,
                                   std::span<const std::uint32_t> triangles, double slack_mm = 2.0);

// The mesh vertex landmark `landmark` marks (the target's embedding or the model's own).
std::uint32_t marked_vertex(const FaceModel& model, const FitTarget& target, int landmark);

// Contour sliding (section 3.2.1, after Yang et al.): project the face vertices, take the 2D
// convex hull, and give each contour landmark the nearest hull vertex; if none is within
// `max_px`, the model's fixed landmark vertex stays.
std::array<int, kFitLandmarkCount> landmark_vertices(const FaceModel& model,
                                                     const FitTarget& target, const Points& x,
                                                     double max_px = 12.0);

}  // namespace fb::fitting_detail
