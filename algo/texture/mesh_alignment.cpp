#include "algo/texture/mesh_alignment.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>
#include <Eigen/Geometry>

namespace fb {

Result<RigidPose> rigid_from_pairs(std::span<const Eigen::Vector3d> model,
                                   std::span<const Eigen::Vector3d> camera) {
  if (model.size() != camera.size() || model.size() < 3)
    return fail(
        "a rigid alignment needs 3 or more landmark pairs; the capture has too few 3D "
        "landmarks (re-detect them or correct them in the kiosk)");
  Eigen::Vector3d cm = Eigen::Vector3d::Zero(), cc = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < model.size(); ++i) {
    cm += model[i];
    cc += camera[i];
  }
  cm /= static_cast<double>(model.size());
  cc /= static_cast<double>(model.size());
  Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < model.size(); ++i)
    h += (model[i] - cm) * (camera[i] - cc).transpose();
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(h, Eigen::ComputeFullU | Eigen::ComputeFullV);
  if (svd.singularValues()(1) < 1e-6 * std::max(1.0, svd.singularValues()(0)))
    return fail("the landmark pairs are collinear; a rigid alignment needs spread-out points");
  Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
  if ((svd.matrixV() * svd.matrixU().transpose()).determinant() < 0) d(2, 2) = -1.0;
  const Eigen::Matrix3d r = svd.matrixV() * d * svd.matrixU().transpose();
  RigidPose pose;
  pose.rotation = Eigen::Quaterniond(r).normalized();
  pose.translation = cc - r * cm;
  return pose;
}

std::vector<std::uint32_t> alignment_samples(int region_vertices, int max_samples) {
  std::vector<std::uint32_t> out;
  if (region_vertices <= 0 || max_samples <= 0) return out;
  const int step = std::max(1, region_vertices / max_samples);
  for (int v = 0; v < region_vertices; v += step) out.push_back(static_cast<std::uint32_t>(v));
  return out;
}

namespace {

// The depth surface at pixel (x, y): its point and normal (towards the camera), if the pixel
// and its four neighbours have depth on one surface.
bool surface_at(const DepthImage& depth, const PinholeIntrinsics& k, int x, int y,
                Eigen::Vector3d& q, Eigen::Vector3d& n) {
  if (x < 1 || y < 1 || x + 1 >= depth.width || y + 1 >= depth.height) return false;
  const double z = depth.at(x, y);
  if (z <= 0) return false;
  const double zl = depth.at(x - 1, y), zr = depth.at(x + 1, y);
  const double zu = depth.at(x, y - 1), zd = depth.at(x, y + 1);
  constexpr double kStep = 15.0;  // mm between neighbours: more is a depth edge
  for (double zn : {zl, zr, zu, zd})
    if (zn <= 0 || std::abs(zn - z) > kStep) return false;
  q = k.unproject(x, y, z);
  const Eigen::Vector3d dx = k.unproject(x + 1, y, zr) - k.unproject(x - 1, y, zl);
  const Eigen::Vector3d dy = k.unproject(x, y + 1, zd) - k.unproject(x, y - 1, zu);
  n = dx.cross(dy);
  const double len = n.norm();
  if (len <= 0) return false;
  n /= len;
  if (n.dot(q) > 0) n = -n;
  return true;
}

}  // namespace

AlignStats align_to_depth(std::span<const float> vertices, std::span<const float> normals,
                          std::span<const std::uint32_t> samples, const DepthImage& depth_mm,
                          const PinholeIntrinsics& intrinsics, RigidPose& camera_from_model,
                          const AlignOptions& options) {
  AlignStats stats;
  struct Pair {
    Eigen::Vector3d x, q, n;
  };
  std::vector<Pair> pairs;
  pairs.reserve(samples.size());
  const int iterations = std::max(1, options.iterations);
  const double settle_rad = options.settle_deg * M_PI / 180.0;
  for (int it = 0; it < iterations + std::max(0, options.settle_iterations); ++it) {
    const double f =
        iterations > 1 ? std::min(1.0, static_cast<double>(it) / (iterations - 1)) : 1.0;
    const double gate = options.first_gate_mm + f * (options.gate_mm - options.first_gate_mm);
    const Eigen::Matrix3d r = camera_from_model.rotation.toRotationMatrix();
    Eigen::Matrix<double, 6, 6> a = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> b = Eigen::Matrix<double, 6, 1>::Zero();
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    stats = AlignStats{};
    double sq = 0.0;
    pairs.clear();
    for (const std::uint32_t v : samples) {
      const Eigen::Vector3d m(vertices[3 * v], vertices[3 * v + 1], vertices[3 * v + 2]);
      const Eigen::Vector3d mn(normals[3 * v], normals[3 * v + 1], normals[3 * v + 2]);
      const Eigen::Vector3d x = r * m + camera_from_model.translation;
      if (x.z() <= 0) continue;
      if ((r * mn).dot(-x.normalized()) < options.min_facing) continue;
      const Eigen::Vector2d px = intrinsics.project(x);
      const int u = static_cast<int>(std::lround(px.x())),
                w = static_cast<int>(std::lround(px.y()));
      if (u < 0 || w < 0 || u >= depth_mm.width || w >= depth_mm.height) continue;
      ++stats.samples;
      Eigen::Vector3d q, n;
      if (!surface_at(depth_mm, intrinsics, u, w, q, n)) continue;
      const double res = n.dot(x - q);
      if (std::abs(res) > gate) continue;
      pairs.push_back({x, q, n});
      centroid += x;
      sq += res * res;
    }
    stats.inliers = static_cast<int>(pairs.size());
    stats.rms_mm = pairs.empty() ? 0.0f : static_cast<float>(std::sqrt(sq / pairs.size()));
    if (pairs.size() < 6) break;
    centroid /= static_cast<double>(pairs.size());
    for (const auto& p : pairs) {
      const double res = p.n.dot(p.x - p.q);
      const double t = res / gate, w = (1.0 - t * t) * (1.0 - t * t);  // Tukey
      Eigen::Matrix<double, 6, 1> j;
      j << (p.x - centroid).cross(p.n), p.n;
      a += w * j * j.transpose();
      b -= w * j * res;
    }
    const Eigen::Matrix<double, 6, 1> d = a.ldlt().solve(b);
    if (!d.allFinite()) break;
    const Eigen::Vector3d omega = d.head<3>();
    const double angle = omega.norm();
    const Eigen::Quaterniond dr = angle > 0
                                      ? Eigen::Quaterniond(Eigen::AngleAxisd(angle, omega / angle))
                                      : Eigen::Quaterniond::Identity();
    camera_from_model.rotation = (dr * camera_from_model.rotation).normalized();
    camera_from_model.translation =
        dr * (camera_from_model.translation - centroid) + centroid + d.tail<3>();
    if (angle < 1e-5 && d.tail<3>().norm() < 1e-3) break;
    // Past the schedule, steps at the final gate until the pose settles.
    if (it + 1 >= iterations && angle < settle_rad && d.tail<3>().norm() < options.settle_mm) break;
  }
  return stats;
}

}  // namespace fb
