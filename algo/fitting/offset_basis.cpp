#include "algo/fitting/offset_basis.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Geometry>

namespace fb {

namespace {

Eigen::Vector3f at(std::span<const float> mesh, std::size_t v) {
  return {mesh[3 * v], mesh[3 * v + 1], mesh[3 * v + 2]};
}

std::vector<Eigen::Vector3f> vertex_normals(const FaceModel& model, std::span<const float> mesh) {
  std::vector<Eigen::Vector3f> out(mesh.size() / 3, Eigen::Vector3f::Zero());
  for (std::size_t t = 0; t + 2 < model.triangles.size(); t += 3) {
    const auto a = model.triangles[t], b = model.triangles[t + 1], c = model.triangles[t + 2];
    const Eigen::Vector3f n = (at(mesh, b) - at(mesh, a)).cross(at(mesh, c) - at(mesh, a));
    out[a] += n, out[b] += n, out[c] += n;
  }
  for (auto& n : out) n = n.norm() > 0 ? n.normalized() : Eigen::Vector3f::Zero();
  return out;
}

// Farthest-point sampling from the first candidate until every candidate is within spacing.
std::vector<Eigen::Vector3f> pick_centres(std::span<const float> mesh,
                                          std::span<const std::uint32_t> candidates,
                                          double spacing_mm) {
  std::vector<Eigen::Vector3f> centres;
  std::vector<float> gap(candidates.size(), std::numeric_limits<float>::infinity());
  std::size_t next = 0;
  while (!candidates.empty()) {
    const Eigen::Vector3f c = at(mesh, candidates[next]);
    centres.push_back(c);
    float far = 0;
    for (std::size_t i = 0; i < candidates.size(); ++i) {
      gap[i] = std::min(gap[i], (at(mesh, candidates[i]) - c).norm());
      if (gap[i] > far) far = gap[i], next = i;
    }
    if (far < spacing_mm) break;
  }
  return centres;
}

// 0 within `radius` of the eyes' and the mouth's landmark vertices, 1 from twice it (smooth).
float feature_hold(const FaceModel& model, std::span<const float> mesh, std::size_t v,
                   double radius) {
  if (radius <= 0) return 1.0f;
  double d = std::numeric_limits<double>::infinity();
  for (std::size_t l = 36; l < 68; ++l)
    d = std::min(d,
                 static_cast<double>((at(mesh, v) - at(mesh, model.landmark_vertices[l])).norm()));
  const double f = std::clamp(d / radius - 1.0, 0.0, 1.0);
  return static_cast<float>(f * f * (3 - 2 * f));
}

}  // namespace

OffsetBasis make_offset_basis(const FaceModel& model, std::span<const float> mesh,
                              std::span<const std::uint32_t> centre_vertices,
                              const OffsetBasisOptions& o) {
  OffsetBasis out;
  const std::size_t nv = mesh.size() / 3;
  out.normal = vertex_normals(model, mesh);
  const std::vector<Eigen::Vector3f> centres = pick_centres(mesh, centre_vertices, o.spacing_mm);
  out.count = static_cast<int>(centres.size());
  const auto reach2 = static_cast<float>(std::pow(o.reach_sigmas * o.sigma_mm, 2));
  const auto inv2s2 = static_cast<float>(1.0 / (2.0 * o.sigma_mm * o.sigma_mm));
  out.first.assign(nv + 1, 0);
  for (std::size_t v = 0; v < nv; ++v) {
    out.first[v] = static_cast<std::uint32_t>(out.entries.size());
    const float hold = feature_hold(model, mesh, v, o.hold_features_mm);
    if (hold <= 0) continue;
    const Eigen::Vector3f p = at(mesh, v);
    for (int k = 0; k < out.count; ++k) {
      const float d2 = (p - centres[static_cast<std::size_t>(k)]).squaredNorm();
      if (d2 < reach2) out.entries.push_back({k, hold * std::exp(-d2 * inv2s2)});
    }
  }
  out.first[nv] = static_cast<std::uint32_t>(out.entries.size());
  return out;
}

void add_offsets(const OffsetBasis& basis, std::span<const double> amplitude_mm,
                 std::span<float> mesh) {
  const std::size_t nv = mesh.size() / 3;
  for (std::size_t v = 0; v < nv; ++v) {
    double s = 0;
    for (const auto& e : basis.of(v))
      s += amplitude_mm[static_cast<std::size_t>(e.bump)] * e.weight;
    if (s == 0) continue;
    for (int a = 0; a < 3; ++a) mesh[3 * v + a] += static_cast<float>(s * basis.normal[v][a]);
  }
}

}  // namespace fb
