#include "algo/fusion/integrator.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

#include "algo/fusion/multiversion.hpp"

namespace fb {
namespace {

// GCC vector extension types of 4 and 8 lanes (a dependent vector_size is not accepted).
template <int kLanes>
struct Lanes;
template <>
struct Lanes<4> {
  using F = float __attribute__((vector_size(16)));
  using I = int __attribute__((vector_size(16)));
  using U16 = std::uint16_t __attribute__((vector_size(8)));
};
template <>
struct Lanes<8> {
  using F = float __attribute__((vector_size(32)));
  using I = int __attribute__((vector_size(32)));
  using U16 = std::uint16_t __attribute__((vector_size(16)));
};

// Everything the voxel loop reads, in the camera frame of the frame being fused.
struct BrickUpdate {
  TsdfVolume* volume = nullptr;
  const int* bricks = nullptr;
  const float* depth_lo = nullptr;  // per brick: depth range of the rays that marked it
  const float* depth_hi = nullptr;
  const Image<float>* depth = nullptr;
  LevelIntrinsics k;
  PixelRect box;
  Eigen::Vector3f step_x, step_y, step_z;  // one voxel along the volume's axes
  Eigen::Vector3f origin_c;                // centre of voxel (0, 0, 0)
  float mu = 8.0f;
  int max_weight = 31;
};

// Updates every voxel of bricks[i0, i1): project its centre, read the pixel's depth,
// sdf = d - z (projective, along the optical axis), tsdf = min(1, sdf / mu); voxels more than
// mu behind the surface are occluded and stay as they are.
// A brick row of 8 voxels is processed as 8 / kLanes vectors of kLanes lanes (GCC/Clang vector
// extensions); only the depth gather is scalar. Branch-free within a vector: voxels outside the
// band are rewritten unchanged.
template <int kLanes>
FB_INLINE inline void update_bricks_impl(const BrickUpdate& a, int i0, int i1) {
  using VF = typename Lanes<kLanes>::F;
  using VI = typename Lanes<kLanes>::I;
  using VU16 = typename Lanes<kLanes>::U16;
  VF lane{};
  for (int i = 0; i < kLanes; ++i) lane[i] = static_cast<float>(i);
  const int nb = a.volume->bricks_per_side();
  const LevelIntrinsics& k = a.k;
  const Eigen::Vector3f &step_x = a.step_x, &step_y = a.step_y, &step_z = a.step_z;
  const float mu = a.mu;
  const float inv_mu = 1.0f / mu;
  const int max_w = a.max_weight;
  const int bx0 = a.box.x0, bx1 = a.box.x1, by0 = a.box.y0, by1 = a.box.y1;
  const int stride = a.depth->width;
  const float* dpix = a.depth->pixels.data();
  const float part_dz = static_cast<float>(kLanes - 1) * step_x.z();
  for (int i = i0; i < i1; ++i) {
    const int b = a.bricks[i];
    const int bx = b % nb, by = (b / nb) % nb, bz = b / (nb * nb);
    Voxel* vox = a.volume->brick_data(b);
    const Eigen::Vector3f base = a.origin_c + step_x * static_cast<float>(bx * 8) +
                                 step_y * static_cast<float>(by * 8) +
                                 step_z * static_cast<float>(bz * 8);
    // Camera depth of the brick's voxel rows is linear in (y, z) and along the row; vectors
    // entirely outside [d_lo - mu, d_hi + mu] are skipped.
    const float keep_lo = a.depth_lo[b] - mu, keep_hi = a.depth_hi[b] + mu;
    for (int z = 0; z < 8; ++z) {
      for (int y = 0; y < 8; ++y) {
        const Eigen::Vector3f p0 =
            base + step_z * static_cast<float>(z) + step_y * static_cast<float>(y);
        Voxel* row = vox + (z << 6) + (y << 3);
        for (int first = 0; first < 8; first += kLanes) {
          const float za = p0.z() + static_cast<float>(first) * step_x.z();
          const float zb = za + part_dz;
          if (std::max(za, zb) < keep_lo || std::min(za, zb) > keep_hi) continue;
          const VF xs = lane + static_cast<float>(first);
          const VF px = p0.x() + xs * step_x.x();
          const VF py = p0.y() + xs * step_x.y();
          const VF pz = p0.z() + xs * step_x.z();
          const VF iz = 1.0f / (pz > 1e-3f ? pz : VF{} + 1e-3f);
          const VI u = __builtin_convertvector(k.fx * px * iz + (k.cx + 0.5f), VI);
          const VI w = __builtin_convertvector(k.fy * py * iz + (k.cy + 0.5f), VI);
          const VI in_box = (u >= bx0) & (u < bx1) & (w >= by0) & (w < by1) & (pz > 0.0f);
          // Out-of-box lanes read pixel 0 (always in the image) and are masked afterwards.
          const VI idx = (w * stride + u) & in_box;
          VF d_read;
          for (int l = 0; l < kLanes; ++l) d_read[l] = dpix[idx[l]];
          const VF d = in_box ? d_read : VF{};
          const VF sdf = d - pz;
          // Per voxel the same band as per vector above, so that 4 and 8 lanes agree.
          const VI update = in_box & (d > 0.0f) & (sdf >= -mu) & (pz >= keep_lo) & (pz <= keep_hi);
          VF f = sdf * inv_mu;
          f = f < 1.0f ? f : VF{} + 1.0f;
          Voxel* cell = row + first;
          VU16 packed;
          std::memcpy(&packed, cell, sizeof packed);
          const VI word = __builtin_convertvector(packed, VI);
          const VI wo = word & Voxel::kMaxWeight;
          const VI to = (word << 16) >> (16 + Voxel::kWeightBits);  // sign-extended TSDF
          // Running average in TSDF units: t' = t + (f * scale - t) / (w + 1).
          const VF tof = __builtin_convertvector(to, VF);
          const VF inv = 1.0f / (__builtin_convertvector(wo, VF) + 1.0f);
          const VF tn = tof + (f * TsdfVolume::kTsdfScale - tof) * inv;
          const VI tq = __builtin_convertvector(tn + (tn >= 0.0f ? VF{} + 0.5f : VF{} - 0.5f), VI);
          const VI wn = wo + 1 < max_w ? wo + 1 : VI{} + max_w;
          const VI out = ((update ? tq : to) << Voxel::kWeightBits) | (update ? wn : wo);
          packed = __builtin_convertvector(out & 0xffff, VU16);
          std::memcpy(static_cast<void*>(cell), &packed, sizeof packed);
        }
      }
    }
  }
}

// 4 lanes: SSE4.1 or SSE2 on x86-64, NEON on the device.
FB_CLONE_X86_64_V2 void update_bricks_4(const BrickUpdate& a, int i0, int i1) {
  update_bricks_impl<4>(a, i0, i1);
}

#if FB_HAVE_X86_64_V3
// 8 lanes, a whole brick row at once, where the CPU has AVX2 and FMA (chosen at run time).
FB_TARGET_X86_64_V3 void update_bricks_8(const BrickUpdate& a, int i0, int i1) {
  update_bricks_impl<8>(a, i0, i1);
}
#endif

}  // namespace

int TsdfIntegrator::widest_lanes() {
#if FB_HAVE_X86_64_V3
  if (cpu_has_x86_64_v3()) return 8;
#endif
  return 4;
}

bool TsdfIntegrator::lanes_supported(int lanes) {
  return lanes == 0 || lanes == 4 || (lanes == 8 && widest_lanes() == 8);
}

void TsdfIntegrator::configure(const FusionOptions& options, const TsdfVolume& volume) {
  lanes_ = options.integrate_lanes == 0 || !lanes_supported(options.integrate_lanes)
               ? widest_lanes()
               : options.integrate_lanes;
  truncation_ = options.truncation_mm;
  max_weight_ = std::clamp(options.max_weight, 1, Voxel::kMaxWeight);
  const std::size_t n = static_cast<std::size_t>(volume.bricks_per_side()) *
                        volume.bricks_per_side() * volume.bricks_per_side();
  marks_.assign(n, 0);
  bricks_.clear();
  bricks_.reserve(n);
  depth_lo_.assign(n, 0.0f);
  depth_hi_.assign(n, 0.0f);
}

FB_CLONE_X86_64_V3 int TsdfIntegrator::integrate(const Image<float>& depth,
                                                 const LevelIntrinsics& k, const PixelRect& box,
                                                 const RigidPoseF& world_from_camera,
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

  // 1. Mark the bricks crossed by the band [d - mu, d + mu] of the rays of every 2x2 pixel block
  // (d from the block's nearest to its farthest valid depth); samples are at most half a brick
  // apart along the ray and 2 px apart across rays, so no brick of the band is skipped at face
  // distances. Each marked brick keeps the depth range [d_lo, d_hi] of the blocks that marked
  // it: its voxels beyond [d_lo - mu, d_hi + mu] are either occluded (never updated) or free
  // space further than the truncation in front of every surface seen through the brick, which
  // is not carved (bricks elsewhere in front of the band are not visited either).
  auto mark_band = [&](const Eigen::Vector3f& gdir, float band_lo, float band_hi, float lo,
                       float hi) FB_INLINE {
    const float z0 = band_lo - mu, z1 = band_hi + mu;
    const int samples = std::max(2, static_cast<int>(std::ceil((z1 - z0) / (0.5f * brick_mm)))) + 1;
    const float dz = (z1 - z0) / static_cast<float>(samples - 1);
    for (int s = 0; s < samples; ++s) {
      const Eigen::Vector3f g = gt + (z0 + dz * static_cast<float>(s)) * gdir;
      if (g.x() < 0 || g.y() < 0 || g.z() < 0) continue;
      const int bx = static_cast<int>(g.x()) >> TsdfVolume::kBrickShift;
      const int by = static_cast<int>(g.y()) >> TsdfVolume::kBrickShift;
      const int bz = static_cast<int>(g.z()) >> TsdfVolume::kBrickShift;
      if (bx >= nb || by >= nb || bz >= nb) continue;
      const int b = (bz * nb + by) * nb + bx;
      if (!marks_[b]) {
        marks_[b] = 1;
        bricks_.push_back(b);
        depth_lo_[b] = lo;
        depth_hi_[b] = hi;
      } else {
        depth_lo_[b] = std::min(depth_lo_[b], lo);
        depth_hi_[b] = std::max(depth_hi_[b], hi);
      }
    }
  };
  bricks_.clear();
  const int x_end = box.x1, y_end = box.y1;
  for (int y = box.y0; y < y_end; y += 2) {
    const float* row = &depth.at(0, y);
    const float* next_row = y + 1 < y_end ? &depth.at(0, y + 1) : row;
    const float ry = (static_cast<float>(y) + 0.5f - k.cy) * ify;
    for (int x = box.x0; x < x_end; x += 2) {
      const int x1 = x + 1 < x_end ? x + 1 : x;
      float lo = 1e30f, hi = 0.0f, first = 0.0f;
      for (const float d : {row[x], row[x1], next_row[x], next_row[x1]}) {
        if (d <= 0.0f) continue;
        if (first == 0.0f) first = d;
        lo = std::min(lo, d);
        hi = std::max(hi, d);
      }
      if (hi <= 0.0f) continue;
      const Eigen::Vector3f ray((static_cast<float>(x) + 0.5f - k.cx) * ifx, ry, 1.0f);
      if (hi - lo <= mu) {
        // The band of one depth of the block marks the bricks (a band over the block's whole
        // range marks ~10 % more bricks for no measurable gain); the range widens what is kept.
        mark_band(gr * ray, first, first, lo, hi);
      } else {
        // A silhouette inside the block: each surface gets its own band (one band from face to
        // background would mark the bricks through the head).
        for (const float d : {row[x], row[x1], next_row[x], next_row[x1]})
          if (d > 0.0f) mark_band(gr * ray, d, d, d, d);
      }
    }
  }
  auto& touched = volume.touched();
  for (int b : bricks_) {
    marks_[b] = 0;
    touched[b] = 1;
  }

  // 2. Update every voxel of the marked bricks.
  const RigidPoseF cam = world_from_camera.inverse();
  BrickUpdate update;
  update.volume = &volume;
  update.bricks = bricks_.data();
  update.depth_lo = depth_lo_.data();
  update.depth_hi = depth_hi_.data();
  update.depth = &depth;
  update.k = k;
  update.box = box;
  update.step_x = cam.r.col(0) * vs;
  update.step_y = cam.r.col(1) * vs;
  update.step_z = cam.r.col(2) * vs;
  update.origin_c = cam.apply(volume.origin() + Eigen::Vector3f::Constant(0.5f * vs));
  update.mu = mu;
  update.max_weight = max_weight_;
  runner.run([&](int part, int parts) {
    int i0, i1;
    ParallelRunner::split(0, static_cast<int>(bricks_.size()), part, parts, i0, i1);
#if FB_HAVE_X86_64_V3
    if (lanes_ == 8) {
      update_bricks_8(update, i0, i1);
      return;
    }
#endif
    update_bricks_4(update, i0, i1);
  });
  return static_cast<int>(bricks_.size());
}

}  // namespace fb
