#include "sim/scoring/fit_metrics.hpp"

#include <Eigen/Core>

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

}  // namespace fb::cli
