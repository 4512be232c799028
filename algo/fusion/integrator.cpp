#include "algo/fusion/integrator.hpp"

#include <algorithm>
#include <cmath>

namespace fb {

void TsdfIntegrator::configure(const FusionOptions& options, const TsdfVolume& volume) {
  truncation_ = options.truncation_mm;
  max_weight_ = std::clamp(options.max_weight, 1, 65535);
  const std::size_t n = static_cast<std::size_t>(volume.bricks_per_side()) *
                        volume.bricks_per_side() * volume.bricks_per_side();
  marks_.assign(n, 0);
  // 1 / (w + 1) for every weight the cap allows (no division per voxel).
  inv_count_.resize(static_cast<std::size_t>(max_weight_) + 1);
  for (int w = 0; w <= max_weight_; ++w) inv_count_[w] = 1.0f / static_cast<float>(w + 1);
  bricks_.clear();
  bricks_.reserve(n);
}

int TsdfIntegrator::integrate(const Image<float>& depth, const LevelIntrinsics& k,
                              const FaceBox& box, const PoseF& world_from_camera,
                              TsdfVolume& volume, ParallelRunner& runner) {
  const float vs = volume.voxel_size();
  const float inv_vs = 1.0f / vs;
  const int nb = volume.bricks_per_side();
  const float brick_mm = vs * TsdfVolume::kBrick;
  const float mu = truncation_;
  // Grid coordinates of a camera point: g = (R p + t - origin) / vs.
  const Eigen::Matrix3f gr = world_from_camera.r * inv_vs;
  const Eigen::Vector3f gt = (world_from_camera.t - volume.origin()) * inv_vs;
  const float ifx = 1.0f / k.fx, ify = 1.0f / k.fy;

  // 1. Mark the bricks crossed by the band [d - mu, d + mu] of every other pixel's ray; samples
  // are at most half a brick apart along the ray and ~2 px apart across rays, so no brick of
  // the band is skipped at face distances.
  const int samples = std::max(2, static_cast<int>(std::ceil(2.0f * mu / (0.5f * brick_mm)))) + 1;
  bricks_.clear();
  for (int y = box.y; y < box.y + box.height; y += 2) {
    const float* row = &depth.at(0, y);
    const float ry = (static_cast<float>(y) - k.cy) * ify;
    for (int x = box.x; x < box.x + box.width; x += 2) {
      const float d = row[x];
      if (d <= 0.0f) continue;
      const Eigen::Vector3f ray((static_cast<float>(x) - k.cx) * ifx, ry, 1.0f);
      const Eigen::Vector3f gdir = gr * ray;
      for (int s = 0; s < samples; ++s) {
        const float z = d - mu + 2.0f * mu * static_cast<float>(s) / (samples - 1);
        const Eigen::Vector3f g = gt + z * gdir;
        const int bx = static_cast<int>(std::floor(g.x())) >> TsdfVolume::kBrickShift;
        const int by = static_cast<int>(std::floor(g.y())) >> TsdfVolume::kBrickShift;
        const int bz = static_cast<int>(std::floor(g.z())) >> TsdfVolume::kBrickShift;
        if (g.x() < 0 || g.y() < 0 || g.z() < 0 || bx >= nb || by >= nb || bz >= nb) continue;
        const int b = (bz * nb + by) * nb + bx;
        if (!marks_[b]) {
          marks_[b] = 1;
          bricks_.push_back(b);
        }
      }
    }
  }
  auto& touched = volume.touched();
  for (int b : bricks_) {
    marks_[b] = 0;
    touched[b] = 1;
  }

  // 2. Update every voxel of the marked bricks: project its centre, read the pixel's depth,
  // sdf = d - z (projective, along the optical axis), tsdf = min(1, sdf / mu); voxels more than
  // mu behind the surface are occluded and stay as they are.
  const PoseF cam = world_from_camera.inverse();
  const Eigen::Vector3f step_x = cam.r.col(0) * vs, step_y = cam.r.col(1) * vs,
                        step_z = cam.r.col(2) * vs;
  const Eigen::Vector3f origin_c =
      cam.apply(volume.origin() + Eigen::Vector3f::Constant(0.5f * vs));
  const float inv_mu = 1.0f / mu;
  const int max_w = max_weight_;
  const float* inv_count = inv_count_.data();
  const int bx0 = box.x, bx1 = box.x + box.width, by0 = box.y, by1 = box.y + box.height;
  const int stride = depth.width;
  const float* dpix = depth.pixels.data();
  runner.run([&](int part, int parts) {
    int i0, i1;
    ParallelRunner::split(0, static_cast<int>(bricks_.size()), part, parts, i0, i1);
    for (int i = i0; i < i1; ++i) {
      const int b = bricks_[i];
      const int bx = b % nb, by = (b / nb) % nb, bz = b / (nb * nb);
      Voxel* vox = volume.brick_data(b);
      const Eigen::Vector3f base = origin_c + step_x * static_cast<float>(bx * 8) +
                                   step_y * static_cast<float>(by * 8) +
                                   step_z * static_cast<float>(bz * 8);
      for (int z = 0; z < 8; ++z) {
        for (int y = 0; y < 8; ++y) {
          const Eigen::Vector3f p0 =
              base + step_z * static_cast<float>(z) + step_y * static_cast<float>(y);
          Voxel* v = vox + (z << 6) + (y << 3);
          // One row of 8 voxels as fixed-length loops over plain arrays, so the compiler
          // vectorises everything but the depth gather (SSE2 here, NEON on the device). The
          // body is branch-free: voxels outside the band are rewritten unchanged.
          float pz[8], su[8], sv[8];
          int idx[8];
          for (int x = 0; x < 8; ++x) {
            const float fx = static_cast<float>(x);
            pz[x] = p0.z() + fx * step_x.z();
            const float iz = 1.0f / std::max(pz[x], 1e-3f);
            su[x] = k.fx * (p0.x() + fx * step_x.x()) * iz + k.cx + 0.5f;
            sv[x] = k.fy * (p0.y() + fx * step_x.y()) * iz + k.cy + 0.5f;
          }
          for (int x = 0; x < 8; ++x) {
            const int u = static_cast<int>(su[x]), w = static_cast<int>(sv[x]);
            const bool in_box = (u >= bx0) & (u < bx1) & (w >= by0) & (w < by1) & (pz[x] > 0.0f);
            idx[x] = in_box ? w * stride + u : -1;
          }
          float d[8];
          for (int x = 0; x < 8; ++x) d[x] = idx[x] >= 0 ? dpix[idx[x]] : 0.0f;
          for (int x = 0; x < 8; ++x) {
            const float sdf = d[x] - pz[x];
            const bool update = (d[x] > 0.0f) & (sdf >= -mu);
            const float f = std::min(1.0f, sdf * inv_mu);
            // Running average in TSDF units: t' = t + (f * scale - t) / (w + 1).
            const int wo = v[x].weight;
            const float to = static_cast<float>(v[x].tsdf);
            const float tn = to + (f * TsdfVolume::kTsdfScale - to) * inv_count[wo];
            v[x].tsdf = static_cast<std::int16_t>(update ? tn : to);
            v[x].weight = static_cast<std::uint16_t>(update ? std::min(wo + 1, max_w) : wo);
          }
        }
      }
    }
  });
  return static_cast<int>(bricks_.size());
}

}  // namespace fb
