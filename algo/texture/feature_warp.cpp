#include "algo/texture/feature_warp.hpp"

#include <algorithm>
#include <cmath>
#include <optional>

#include <Eigen/Dense>

namespace fb {

namespace {

// A model-frame point's position in the colour image of a view posed at `pose`.
std::optional<Eigen::Vector2d> color_px(const KinectRegistration& registration,
                                        const PinholeIntrinsics& k, const RigidPose& pose,
                                        const Eigen::Vector3d& m) {
  const Eigen::Vector3d x = pose.apply(m);
  if (x.z() <= 0.0) return std::nullopt;
  const Eigen::Vector2d px = k.project(x);
  Eigen::Vector2d c;
  if (!registration.depth_to_color_interpolated(px.x(), px.y(), x.z(), c.x(), c.y()))
    return std::nullopt;
  return c;
}

// One landmark in one view: the image's local Jacobian along the vertex's tangent plane
// (px per mm) and the detected point's offset from the vertex's projection.
struct Pull {
  Eigen::Matrix2d jacobian;
  Eigen::Vector2d residual;
};

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

// The tangential offset (tangent-plane coordinates, mm) that best brings the projections onto
// the detected points: Huber IRLS with a zero-mean prior.
Eigen::Vector2d solve_offset(const std::vector<Pull>& pulls, const FeatureWarpOptions& o) {
  Eigen::Vector2d d = Eigen::Vector2d::Zero();
  for (int it = 0; it < 6; ++it) {
    Eigen::Matrix2d a = Eigen::Matrix2d::Identity() / (o.prior_mm * o.prior_mm);
    Eigen::Vector2d b = Eigen::Vector2d::Zero();
    for (const Pull& p : pulls) {
      const double e = (p.jacobian * d - p.residual).norm();
      const double w = (e <= o.noise_px ? 1.0 : o.noise_px / e) / (o.noise_px * o.noise_px);
      a += w * p.jacobian.transpose() * p.jacobian;
      b += w * p.jacobian.transpose() * p.residual;
    }
    d = a.ldlt().solve(b);
  }
  return d;
}

}  // namespace

Result<FeatureWarp> estimate_feature_warp(std::span<const float> vertices,
                                          std::span<const float> normals,
                                          std::span<const std::uint32_t> landmark_vertices,
                                          std::span<const FeatureView> views,
                                          const KinectRegistration& registration,
                                          const FeatureWarpOptions& options) {
  const std::size_t n = vertices.size() / 3;
  if (normals.size() != vertices.size()) return fail("the mesh's normals do not match it");
  if (landmark_vertices.size() != 68) return fail("the feature warp needs the 68 points' vertices");
  for (const auto v : landmark_vertices)
    if (v >= n) return fail("a landmark vertex is outside the mesh");
  FeatureWarp out;
  out.offsets.assign(vertices.size(), 0.0f);
  out.views = static_cast<int>(views.size());
  const PinholeIntrinsics k = registration.depth_intrinsics();
  auto at = [](std::span<const float> a, std::size_t v) {
    return Eigen::Vector3d(a[3 * v], a[3 * v + 1], a[3 * v + 2]);
  };
  std::vector<Eigen::Vector3d> centres, offsets;
  std::vector<double> before, after;
  constexpr double kStepMm = 0.5;
  for (int l = std::max(0, options.first_landmark); l < 68; ++l) {
    const std::size_t v = landmark_vertices[static_cast<std::size_t>(l)];
    const Eigen::Vector3d m = at(vertices, v);
    const Eigen::Vector3d normal = at(normals, v).normalized();
    const Eigen::Vector3d t1 = normal.unitOrthogonal(), t2 = normal.cross(t1);
    std::vector<Pull> pulls;
    for (const FeatureView& view : views) {
      const Eigen::Vector3d x = view.camera_from_model.apply(m);
      if ((view.camera_from_model.rotation * normal).dot(-x.normalized()) < options.min_facing)
        continue;
      const auto c0 = color_px(registration, k, view.camera_from_model, m);
      const auto c1 = color_px(registration, k, view.camera_from_model, m + kStepMm * t1);
      const auto c2 = color_px(registration, k, view.camera_from_model, m + kStepMm * t2);
      if (!c0 || !c1 || !c2) continue;
      Pull p;
      p.jacobian.col(0) = (*c1 - *c0) / kStepMm;
      p.jacobian.col(1) = (*c2 - *c0) / kStepMm;
      p.residual = view.points[static_cast<std::size_t>(l)] - *c0;
      pulls.push_back(p);
    }
    if (static_cast<int>(pulls.size()) < std::max(1, options.min_views)) continue;
    Eigen::Vector2d d = solve_offset(pulls, options);
    if (d.norm() > options.max_offset_mm) d *= options.max_offset_mm / d.norm();
    for (const Pull& p : pulls) {
      before.push_back(p.residual.norm());
      after.push_back((p.jacobian * d - p.residual).norm());
    }
    centres.push_back(m);
    offsets.push_back(d.x() * t1 + d.y() * t2);
    out.mean_offset_mm += d.norm();
  }
  out.landmarks = static_cast<int>(centres.size());
  if (centres.empty()) return out;
  out.mean_offset_mm /= static_cast<double>(centres.size());
  out.residual_px_before = median(before);
  out.residual_px_after = median(after);
  // Kernel smoother over the mesh: the weighted mean of nearby landmarks' offsets, fading to
  // zero where the kernel mass is small (no landmark near: cheeks, scalp, neck).
  const double inv = 1.0 / (2.0 * options.kernel_mm * options.kernel_mm);
  const double reach2 = 16.0 * options.kernel_mm * options.kernel_mm;
  for (std::size_t v = 0; v < n; ++v) {
    const Eigen::Vector3d p = at(vertices, v);
    Eigen::Vector3d num = Eigen::Vector3d::Zero();
    double den = 0.0;
    for (std::size_t c = 0; c < centres.size(); ++c) {
      const double d2 = (p - centres[c]).squaredNorm();
      if (d2 > reach2) continue;
      const double g = std::exp(-d2 * inv);
      num += g * offsets[c];
      den += g;
    }
    if (den <= 0.0) continue;
    const Eigen::Vector3d o = num / std::max(den, options.fade);
    for (int a = 0; a < 3; ++a) out.offsets[3 * v + a] = static_cast<float>(o[a]);
  }
  return out;
}

}  // namespace fb
