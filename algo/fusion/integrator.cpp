#include "algo/fusion/integrator.hpp"

#include <algorithm>
#include <cmath>

namespace fb {
namespace {

using V4f = float __attribute__((vector_size(16)));
using V4i = int __attribute__((vector_size(16)));
constexpr V4f kLane = {0.0f, 1.0f, 2.0f, 3.0f};
constexpr V4f kHalf = {0.5f, 0.5f, 0.5f, 0.5f};

}  // namespace

void TsdfIntegrator::configure(const FusionOptions& options, const TsdfVolume& volume) {
  truncation_ = options.truncation_mm;
  max_weight_ = std::clamp(options.max_weight, 1, Voxel::kMaxWeight);
  const std::size_t n = static_cast<std::size_t>(volume.bricks_per_side()) *
                        volume.bricks_per_side() * volume.bricks_per_side();
  marks_.assign(n, 0);
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
          // One row of 8 voxels as two 4-lane vectors (GCC/Clang vector extensions: SSE2 here,
          // NEON on the device); only the depth gather is scalar. Branch-free: voxels outside
          // the band are rewritten unchanged.
          for (int half = 0; half < 2; ++half) {
            const V4f xs = kLane + static_cast<float>(4 * half);
            const V4f px = p0.x() + xs * step_x.x();
            const V4f py = p0.y() + xs * step_x.y();
            const V4f pz = p0.z() + xs * step_x.z();
            const V4f iz = 1.0f / (pz > 1e-3f ? pz : V4f{1e-3f, 1e-3f, 1e-3f, 1e-3f});
            const V4i u = __builtin_convertvector(k.fx * px * iz + (k.cx + 0.5f), V4i);
            const V4i w = __builtin_convertvector(k.fy * py * iz + (k.cy + 0.5f), V4i);
            const V4i in_box = (u >= bx0) & (u < bx1) & (w >= by0) & (w < by1) & (pz > 0.0f);
            const V4i idx = w * stride + u;
            V4f d;
            for (int i = 0; i < 4; ++i) d[i] = in_box[i] ? dpix[idx[i]] : 0.0f;
            const V4f sdf = d - pz;
            const V4i update = in_box & (d > 0.0f) & (sdf >= -mu);
            V4f f = sdf * inv_mu;
            f = f < 1.0f ? f : V4f{1.0f, 1.0f, 1.0f, 1.0f};
            Voxel* cell = v + 4 * half;
            V4i word;
            for (int i = 0; i < 4; ++i) word[i] = cell[i].word;
            const V4i wo = word & Voxel::kMaxWeight;
            const V4i to = (word << 16) >> (16 + Voxel::kWeightBits);  // sign-extended TSDF
            // Running average in TSDF units: t' = t + (f * scale - t) / (w + 1).
            const V4f tof = __builtin_convertvector(to, V4f);
            const V4f inv = 1.0f / (__builtin_convertvector(wo, V4f) + 1.0f);
            const V4f tn = tof + (f * TsdfVolume::kTsdfScale - tof) * inv;
            const V4i tq = __builtin_convertvector(tn + (tn >= 0.0f ? kHalf : -kHalf), V4i);
            const V4i wn = wo + 1 < max_w ? wo + 1 : V4i{max_w, max_w, max_w, max_w};
            const V4i out = ((update ? tq : to) << Voxel::kWeightBits) | (update ? wn : wo);
            for (int i = 0; i < 4; ++i) cell[i].word = static_cast<std::uint16_t>(out[i]);
          }
        }
      }
    }
  });
  return static_cast<int>(bricks_.size());
}

}  // namespace fb
