#include "algo/tracking/rigid_icp.hpp"

#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

namespace fb {

IcpStats RigidIcp::run(const SubjectRig& rig, const TrackerCamera& camera,
                       const OcclusionMask& mask, const Image<float>& image, const PixelRect& b,
                       RigidPoseF& p, int iterations, float first_gate, float gate) const {
  IcpStats stats;
  const int n = rig.n;
  const float width = static_cast<float>(camera.width), height = static_cast<float>(camera.height);
  for (int it = 0; it < iterations; ++it) {
    // Gate shrinks geometrically from first_gate to gate over the first iterations.
    const float c = std::max(gate, first_gate * std::pow(0.5f, static_cast<float>(it)));
    const Eigen::Vector3f pivot = p.r * rig.centroid + p.t;
    Eigen::Matrix<float, 6, 6> jtj = Eigen::Matrix<float, 6, 6>::Zero();
    Eigen::Matrix<float, 6, 1> jtr = Eigen::Matrix<float, 6, 1>::Zero();
    IcpStats s;
    double r2 = 0.0;
    for (int i = 0; i < n; ++i) {
      Eigen::Vector3f x, nn, q;
      if (!rig.facing_sample(p, i, x, nn)) continue;
      const Eigen::Vector2f px = camera.pixel_of(x);
      const float u = px.x(), v = px.y();
      if (u < 0.0f || v < 0.0f || u > width - 1.0f || v > height - 1.0f) continue;
      // Hidden samples are not expected to be seen: the inlier fraction of loss detection is of
      // the visible ones (min_inliers still reports a face covered entirely).
      if (mask.hides_sample(i)) {
        ++s.hidden;
        continue;
      }
      ++s.facing;
      if (!camera.measured_point(image, b, x, q)) continue;
      ++s.used;
      const float r = nn.dot(x - q);
      const float w = tukey(r, c);
      if (w <= 0.0f) continue;
      ++s.inliers;
      r2 += static_cast<double>(r) * r;
      Eigen::Matrix<float, 6, 1> j;
      j.head<3>() = (x - pivot).cross(nn);
      j.tail<3>() = nn;
      jtj.noalias() += w * j * j.transpose();
      jtr.noalias() += w * r * j;
    }
    s.rms = s.inliers > 0 ? static_cast<float>(std::sqrt(r2 / s.inliers)) : 1e9f;
    stats = s;
    if (s.inliers < 12) break;
    jtj.diagonal().array() += 1e-3f;
    const Eigen::Matrix<float, 6, 1> xi = jtj.ldlt().solve(-jtr);
    p.apply_twist(xi.head<3>(), xi.tail<3>(), pivot);
    const float angle = xi.head<3>().norm();
    // Orthonormalise now and then against float drift.
    if (it == iterations - 1) p.r = Eigen::Quaternionf(p.r).normalized().toRotationMatrix();
    if (angle < options_.icp_converged_rad && xi.tail<3>().norm() < options_.icp_converged_mm &&
        it > 0)
      break;
  }
  return stats;
}

}  // namespace fb
