#include "algo/fitting/fit_correspondence.hpp"

#include "algo/render/rasterizer.hpp"

namespace fb::fitting_detail {

std::vector<char> visible_vertices(const FitTarget& t, const Points& x,
                                   std::span<const std::uint32_t> triangles, double slack_mm) {
  std::vector<Eigen::Vector3f> v(static_cast<std::size_t>(x.rows()));
  for (Eigen::Index i = 0; i < x.rows(); ++i)
    v[static_cast<std::size_t>(i)] = x.row(i).transpose().cast<float>();
  RasterBuffers rb;
  rb.reset(t.intrinsics.width, t.intrinsics.height);
  std::vector<char> vis(static_cast<std::size_t>(x.rows()), 0);
  if (!rasterize(t.intrinsics, v, triangles, RasterOptions{}, rb)) return vis;
  for (Eigen::Index i = 0; i < x.rows(); ++i) {
    if (x(i, 2) <= 1.0) continue;
    const Eigen::Vector2d uv = t.intrinsics.project(x.row(i).transpose());
    const int px = static_cast<int>(std::lround(uv.x())),
              py = static_cast<int>(std::lround(uv.y()));
    if (px < 0 || py < 0 || px >= rb.width || py >= rb.height) continue;
    vis[static_cast<std::size_t>(i)] = x(i, 2) <= rb.depth[rb.index(px, py)] + slack_mm;
  }
  return vis;
}

std::uint32_t marked_vertex(const FaceModel& model, const FitTarget& target, int landmark) {
  const auto i = static_cast<std::size_t>(landmark);
  return target.landmark_vertices ? (*target.landmark_vertices)[i] : model.landmark_vertices[i];
}

std::array<int, kFitLandmarkCount> landmark_vertices(const FaceModel& model,
                                                     const FitTarget& target, const Points& x,
                                                     double max_px) {
  std::array<int, kFitLandmarkCount> out{};
  for (int i = 0; i < kFitLandmarkCount; ++i)
    out[static_cast<std::size_t>(i)] = static_cast<int>(marked_vertex(model, target, i));
  std::vector<Eigen::Vector2d> proj;
  std::vector<int> ids;
  proj.reserve(model.fitting_vertices.size());
  for (std::uint32_t v : model.fitting_vertices) {
    const Eigen::Vector3d p = x.row(v).transpose();
    if (p.z() <= 1.0) continue;
    proj.push_back(target.intrinsics.project(p));
    ids.push_back(static_cast<int>(v));
  }
  const std::vector<int> hull = convex_hull(proj);
  for (int k = 0; k <= 16; ++k) {
    const FitLandmark& lm = target.landmarks[static_cast<std::size_t>(k)];
    if (!lm.valid) continue;
    double best = max_px * max_px;
    for (int h : hull) {
      const double d = (proj[static_cast<std::size_t>(h)] - lm.pixel).squaredNorm();
      if (d < best) {
        best = d;
        out[static_cast<std::size_t>(k)] = ids[static_cast<std::size_t>(h)];
      }
    }
  }
  return out;
}

}  // namespace fb::fitting_detail
