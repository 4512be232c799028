#include "sim/scoring/fit_metrics.hpp"

#include <cmath>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/SVD>  // Eigen::umeyama

namespace fb::cli {

std::vector<std::uint32_t> eye_mouth_vertices(const FaceModel& model, double radius_mm) {
  std::vector<float> mean(static_cast<std::size_t>(model.vertex_count) * 3);
  model.evaluate({}, {}, mean);
  auto at = [&](std::uint32_t v) {
    return Eigen::Vector3d(mean[3 * v], mean[3 * v + 1], mean[3 * v + 2]);
  };
  std::vector<Eigen::Vector3d> centres;
  for (int l = 36; l < 68; ++l) centres.push_back(at(model.landmark_vertices[l]));
  std::vector<std::uint32_t> out;
  for (std::uint32_t v : model.fitting_vertices) {
    const Eigen::Vector3d p = at(v);
    for (const auto& c : centres)
      if ((p - c).norm() <= radius_mm) {
        out.push_back(v);
        break;
      }
  }
  return out;
}

void append_vertex_distances(std::span<const float> a, const RigidPose& pose_a,
                             std::span<const float> b, const RigidPose& pose_b,
                             std::span<const std::uint32_t> subset, std::vector<double>& out) {
  for (std::uint32_t v : subset) {
    const std::size_t i = 3 * static_cast<std::size_t>(v);
    if (i + 2 >= a.size() || i + 2 >= b.size()) continue;
    out.push_back(
        (pose_a.apply({a[i], a[i + 1], a[i + 2]}) - pose_b.apply({b[i], b[i + 1], b[i + 2]}))
            .norm());
  }
}

VertexErrorParts vertex_error_parts(std::span<const float> fitted, const RigidPose& pose_fitted,
                                    std::span<const float> truth, const RigidPose& pose_truth,
                                    std::span<const std::uint32_t> subset,
                                    std::span<const std::uint32_t> triangles) {
  VertexErrorParts out;
  if (!triangles.empty()) {  // area-weighted normals of the posed truth
    const std::size_t n = truth.size() / 3;
    std::vector<Eigen::Vector3d> p(n), nrm(n, Eigen::Vector3d::Zero());
    for (std::size_t i = 0; i < n; ++i)
      p[i] = pose_truth.apply({truth[3 * i], truth[3 * i + 1], truth[3 * i + 2]});
    for (std::size_t t = 0; t + 2 < triangles.size(); t += 3) {
      const Eigen::Vector3d f =
          (p[triangles[t + 1]] - p[triangles[t]]).cross(p[triangles[t + 2]] - p[triangles[t]]);
      for (int k = 0; k < 3; ++k) nrm[triangles[t + static_cast<std::size_t>(k)]] += f;
    }
    double sn = 0, st = 0;
    int count = 0;
    for (std::uint32_t v : subset) {
      const std::size_t i = 3 * static_cast<std::size_t>(v);
      if (v >= n || i + 2 >= fitted.size() || nrm[v].norm() == 0) continue;
      const Eigen::Vector3d e = pose_fitted.apply({fitted[i], fitted[i + 1], fitted[i + 2]}) - p[v];
      const Eigen::Vector3d u = nrm[v].normalized();
      sn += std::abs(e.dot(u));
      st += (e - e.dot(u) * u).norm();
      ++count;
    }
    if (count) {
      out.normal_mm = sn / count;
      out.tangential_mm = st / count;
    }
  }
  std::vector<Eigen::Vector3d> a, b;
  for (std::uint32_t v : subset) {
    const std::size_t i = 3 * static_cast<std::size_t>(v);
    if (i + 2 >= fitted.size() || i + 2 >= truth.size()) continue;
    a.push_back(pose_fitted.apply({fitted[i], fitted[i + 1], fitted[i + 2]}));
    b.push_back(pose_truth.apply({truth[i], truth[i + 1], truth[i + 2]}));
  }
  if (a.empty()) return out;
  Eigen::Vector3d ca = Eigen::Vector3d::Zero(), cb = Eigen::Vector3d::Zero();
  for (std::size_t k = 0; k < a.size(); ++k) {
    ca += a[k];
    cb += b[k];
  }
  ca /= static_cast<double>(a.size());
  cb /= static_cast<double>(b.size());
  out.mean_offset_mm = ca - cb;
  double moved = 0;
  Eigen::Matrix3Xd src(3, static_cast<Eigen::Index>(a.size())), dst(3, src.cols());
  for (std::size_t k = 0; k < a.size(); ++k) {
    moved += ((a[k] - ca) - (b[k] - cb)).norm();
    src.col(static_cast<Eigen::Index>(k)) = a[k];
    dst.col(static_cast<Eigen::Index>(k)) = b[k];
  }
  out.after_translation_mm = moved / static_cast<double>(a.size());
  // The best rigid motion of the fitted shape onto the truth's, as elsewhere (Eigen's Umeyama).
  const Eigen::Matrix4d m = Eigen::umeyama(src, dst, false);
  const Eigen::Matrix3d r = m.topLeftCorner<3, 3>();
  const Eigen::Vector3d t = m.topRightCorner<3, 1>();
  double rigid = 0;
  for (std::size_t k = 0; k < a.size(); ++k) rigid += (r * a[k] + t - b[k]).norm();
  out.after_rigid_mm = rigid / static_cast<double>(a.size());
  out.rigid_rotation_deg = Eigen::AngleAxisd(r).angle() * 180.0 / M_PI;
  const Eigen::Matrix4d ms = Eigen::umeyama(src, dst, true);
  const Eigen::Matrix3d sr = ms.topLeftCorner<3, 3>();
  const Eigen::Vector3d st = ms.topRightCorner<3, 1>();
  double similar = 0;
  for (std::size_t k = 0; k < a.size(); ++k) similar += (sr * a[k] + st - b[k]).norm();
  out.after_similarity_mm = similar / static_cast<double>(a.size());
  out.similarity_scale = std::cbrt(sr.determinant());
  return out;
}

}  // namespace fb::cli
