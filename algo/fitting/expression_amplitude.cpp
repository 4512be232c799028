#include "algo/fitting/expression_amplitude.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Cholesky>

#include "algo/fitting/fit_correspondence.hpp"

namespace fb {

using namespace fitting_detail;

namespace {

// The vertices some part moves by at least `moving_mm`: the only ones whose residual depends
// on the amplitudes.
std::vector<int> moving_vertices(const FaceModel& model, std::span<const std::vector<float>> parts,
                                 double moving_mm) {
  std::vector<int> out;
  const double m2 = moving_mm * moving_mm;
  for (std::uint32_t v : model.fitting_vertices) {
    const std::size_t i = 3 * std::size_t{v};
    for (const auto& d : parts) {
      if (d[i] * d[i] + d[i + 1] * d[i + 1] + d[i + 2] * d[i + 2] >= m2) {
        out.push_back(static_cast<int>(v));
        break;
      }
    }
  }
  std::sort(out.begin(), out.end());
  return out;
}

// Vertex v at amplitudes `a`, posed: R (start_v + sum_k (a_k - 1) D_k,v) + t.
Eigen::Vector3d vertex_at(std::span<const float> start, std::span<const std::vector<float>> parts,
                          const Eigen::VectorXd& a, const Eigen::Matrix3d& r,
                          const Eigen::Vector3d& t, int v) {
  const std::size_t i = 3 * static_cast<std::size_t>(v);
  Eigen::Vector3d p(start[i], start[i + 1], start[i + 2]);
  for (std::size_t k = 0; k < parts.size(); ++k) {
    const auto& d = parts[k];
    p += (a[static_cast<Eigen::Index>(k)] - 1.0) * Eigen::Vector3d(d[i], d[i + 1], d[i + 2]);
  }
  return r * p + t;
}

// Accumulates one weighted residual block (rows of J and r) into the normal equations.
template <int Rows>
void accumulate(const Eigen::Matrix<double, Rows, Eigen::Dynamic>& j,
                const Eigen::Matrix<double, Rows, 1>& r, double w, Eigen::MatrixXd& h,
                Eigen::VectorXd& g) {
  h.noalias() += w * j.transpose() * j;
  g.noalias() += w * j.transpose() * r;
}

}  // namespace

Result<std::vector<double>> fit_amplitudes(const FaceModel& model, const FitTarget& target,
                                           std::span<const float> start,
                                           const RigidPose& camera_from_model,
                                           std::span<const std::vector<float>> parts,
                                           const AmplitudeOptions& o) {
  const std::size_t n3 = static_cast<std::size_t>(model.vertex_count) * 3;
  if (start.size() != n3) return fail("amplitude fit: the start mesh has the wrong vertex count");
  for (const auto& d : parts)
    if (d.size() != n3) return fail("amplitude fit: a part has the wrong vertex count");
  const int kp = static_cast<int>(parts.size());
  std::vector<double> out(parts.size(), 1.0);
  if (kp == 0) return out;
  const std::vector<int> moving = moving_vertices(model, parts, o.moving_mm);
  if (moving.empty()) return out;

  const Eigen::Matrix3d r = camera_from_model.rotation.toRotationMatrix();
  const Eigen::Vector3d t = camera_from_model.translation;
  // Visibility, normals and the contour's vertices of the start: the amplitudes move the mouth
  // and brows by millimetres, which changes none of them much, and recomputing them (a
  // rasterisation of the whole mesh) each step would cost more than the fit.
  const Points x0 = posed(to_points(start), r, t);
  const Points vn = vertex_normals(x0, model.triangles);
  const std::vector<char> vis = visible_vertices(target, x0, model.triangles);
  const auto lm_verts = landmark_vertices(model, target, x0);
  const double cos_min = std::cos(o.max_normal_angle_deg * M_PI / 180.0);
  Eigen::VectorXd a = Eigen::VectorXd::Ones(kp);
  Eigen::Matrix<double, 1, Eigen::Dynamic> j1(1, kp);
  Eigen::Matrix<double, 3, Eigen::Dynamic> j3(3, kp);
  for (int it = 0; it < o.iterations; ++it) {
    Eigen::MatrixXd h = o.prior * Eigen::MatrixXd::Identity(kp, kp);
    Eigen::VectorXd g = o.prior * (a - Eigen::VectorXd::Ones(kp));
    auto part_jacobian = [&](int v, Eigen::Matrix<double, 3, Eigen::Dynamic>& j) {
      const std::size_t i = 3 * static_cast<std::size_t>(v);
      for (int k = 0; k < kp; ++k) {
        const auto& d = parts[static_cast<std::size_t>(k)];
        j.col(k) = r * Eigen::Vector3d(d[i], d[i + 1], d[i + 2]);
      }
    };
    for (int v : moving) {
      if (!vis[static_cast<std::size_t>(v)]) continue;
      const Eigen::Vector3d p = vertex_at(start, parts, a, r, t, v);
      Correspondence c;
      if (!correspond(target, p, vn.row(v).transpose(), o.max_distance_mm, cos_min, c) ||
          behind_hair(c, p))
        continue;
      part_jacobian(v, j3);
      j1 = c.n.transpose() * j3;
      const Eigen::Matrix<double, 1, 1> res(c.n.dot(p - c.q));
      const double u = o.robust_scale_mm > 0 ? res[0] / o.robust_scale_mm : 0.0;
      accumulate<1>(j1, res, c.confidence / (1.0 + u * u), h, g);
    }
    for (int l = 0; l < kFitLandmarkCount; ++l) {
      const FitLandmark& lm = target.landmarks[static_cast<std::size_t>(l)];
      const int v = lm_verts[static_cast<std::size_t>(l)];
      if (!lm.valid || !std::binary_search(moving.begin(), moving.end(), v)) continue;
      const Eigen::Vector3d p = vertex_at(start, parts, a, r, t, v);
      part_jacobian(v, j3);
      Eigen::Vector3d res;
      if (lm.point && !is_contour_landmark(l)) {
        res = p - *lm.point;
      } else {  // 2D: the distance to the viewing ray, across it
        const Eigen::Vector3d d = ray(target.intrinsics, lm.pixel).normalized();
        const Eigen::Matrix3d across = Eigen::Matrix3d::Identity() - d * d.transpose();
        res = across * p;
        j3 = across * j3;
      }
      const double len = res.norm();
      const double huber = len > o.landmark_huber_mm ? o.landmark_huber_mm / len : 1.0;
      accumulate<3>(j3, res, o.w_fea * huber, h, g);
    }
    const Eigen::VectorXd step = -h.ldlt().solve(g);
    if (!step.allFinite()) return fail("amplitude fit: the solve diverged");
    a = (a + step).cwiseMax(o.min_amplitude).cwiseMin(o.max_amplitude);
    if (step.cwiseAbs().maxCoeff() < 1e-3) break;
  }
  for (int k = 0; k < kp; ++k) out[static_cast<std::size_t>(k)] = a[k];
  return out;
}

}  // namespace fb
