#include "algo/photo/photo_face.hpp"

#include <algorithm>

namespace fb {

Result<PhotoFace> fit_photo_face(const BilinearModel& model, const ImageLandmarks& landmarks,
                                 const LandmarkFitOptions& options) {
  auto fit = fit_landmarks(model, landmarks, options);
  if (!fit) return fit.failure();
  PhotoFace face;
  face.fit = std::move(*fit);
  face.mesh.resize(static_cast<std::size_t>(model.coordinate_count()));
  model.evaluate(face.fit.w_id, face.fit.w_exp, face.mesh);
  face.blendshapes = image_blendshapes(model, face.fit.w_id);
  return face;
}

void blend_image_blendshapes(const std::vector<std::vector<float>>& b, std::span<const float> beta,
                             std::span<const float> base, std::span<float> out) {
  const std::vector<float>& b0 = b.front();
  if (base.empty()) {
    std::copy(b0.begin(), b0.end(), out.begin());
  } else {
    std::copy(base.begin(), base.end(), out.begin());
  }
  for (std::size_t i = 1; i < b.size() && i - 1 < beta.size(); ++i) {
    const float w = beta[i - 1];
    if (w == 0.0f) continue;
    const std::vector<float>& bi = b[i];
    for (std::size_t k = 0; k < out.size(); ++k) out[k] += w * (bi[k] - b0[k]);
  }
}

std::vector<Eigen::Vector3f> project_mesh(const WeakPerspectivePose& pose,
                                          std::span<const float> mesh) {
  const Eigen::Matrix3d sr = pose.scale * pose.rotation;
  std::vector<Eigen::Vector3f> out(mesh.size() / 3);
  for (std::size_t v = 0; v < out.size(); ++v) {
    const Eigen::Vector3d p = sr * Eigen::Vector3d(mesh[3 * v], mesh[3 * v + 1], mesh[3 * v + 2]);
    out[v] = Eigen::Vector3f(static_cast<float>(p.x() + pose.translation.x()),
                             static_cast<float>(p.y() + pose.translation.y()),
                             static_cast<float>(p.z()));
  }
  return out;
}

std::vector<std::uint32_t> face_region_triangles(const BilinearModel& model) {
  const auto n = static_cast<std::uint32_t>(model.face_vertex_count);
  std::vector<std::uint32_t> out;
  for (std::size_t t = 0; t + 2 < model.triangles.size(); t += 3) {
    const std::uint32_t a = model.triangles[t], b = model.triangles[t + 1],
                        c = model.triangles[t + 2];
    if (a < n && b < n && c < n) out.insert(out.end(), {a, b, c});
  }
  return out;
}

std::vector<Eigen::Vector2f> mouth_polygon(const BilinearModel& model,
                                           std::span<const Eigen::Vector3f> projected) {
  std::vector<Eigen::Vector2f> out;
  for (int k = 60; k < 68; ++k) {
    const std::uint32_t v = model.landmark_vertices[static_cast<std::size_t>(k)];
    if (v < projected.size()) out.push_back(projected[v].head<2>());
  }
  return out;
}

Result<ColorImage> warp_face(const ColorImage& photo, const BilinearModel& model,
                             const WeakPerspectivePose& pose, std::span<const float> from,
                             std::span<const float> to, std::span<const std::uint32_t> triangles,
                             const MeshWarpOptions& options, MeshWarpStats* stats) {
  const auto source3 = project_mesh(pose, from);
  const auto target = project_mesh(pose, to);
  std::vector<Eigen::Vector2f> source(source3.size());
  for (std::size_t v = 0; v < source.size(); ++v) source[v] = source3[v].head<2>();
  const auto mouth = mouth_polygon(model, target);
  MeshWarpInput in{triangles, source, target, mouth};
  return warp_photo(photo, in, options, stats);
}

}  // namespace fb
