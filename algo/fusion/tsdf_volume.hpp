// The TSDF volume object: a dense cube of voxels stored brick by brick (8^3 voxels per brick,
// so one brick is 1 KB of contiguous memory and the integrator and ray caster touch few cache
// lines). Each voxel is one 16-bit word: an 11-bit signed TSDF (tsdf in [-1, 1] * 1023, steps
// of truncation / 1023, ~0.008 mm at 8 mm) and a 5-bit weight (0 = unseen, capped at 31). Two
// bytes instead of four halve the memory traffic, which is what the ray caster waits on; a
// weight cap of 31 is a running average with alpha = 1/32, whose noise reduction equals a
// 63-frame mean.
// The voxels live in anonymous zero pages mapped for the volume: a page is resident only once a
// brick in it is written, so the 32 MB cube costs the memory of the bricks a take integrates
// (the face's band), not the whole cube (reads of untouched bricks see the shared zero page).
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include <Eigen/Core>

#include "algo/core/result.hpp"

namespace fb {

struct Voxel {
  std::uint16_t word = 0;

  static constexpr int kWeightBits = 5;
  static constexpr int kMaxWeight = (1 << kWeightBits) - 1;
  int tsdf() const { return static_cast<std::int16_t>(word) >> kWeightBits; }  // arithmetic
  int weight() const { return word & kMaxWeight; }
  void set(int tsdf_q, int w) {
    word = static_cast<std::uint16_t>((static_cast<unsigned>(tsdf_q) << kWeightBits) |
                                      static_cast<unsigned>(w));
  }
};

// munmap of a TsdfVolume's voxel pages.
struct VoxelPagesDeleter {
  std::size_t bytes = 0;
  void operator()(Voxel* pages) const;
};

class TsdfVolume {
 public:
  static constexpr int kBrickShift = 3;
  static constexpr int kBrick = 1 << kBrickShift;  // voxels per brick side
  static constexpr float kTsdfScale = 1023.0f;

  // Allocates (once) and clears a resolution^3 volume with its corner at `origin_mm` (world).
  Result<void> reset(int resolution, float size_mm, const Eigen::Vector3f& origin_mm);
  // Clears the voxels without reallocating; keeps the geometry.
  void clear();
  void set_origin(const Eigen::Vector3f& origin_mm) { origin_ = origin_mm; }

  int resolution() const { return resolution_; }
  int bricks_per_side() const { return bricks_; }
  float voxel_size() const { return voxel_size_; }
  float size_mm() const { return voxel_size_ * static_cast<float>(resolution_); }
  const Eigen::Vector3f& origin() const { return origin_; }
  std::size_t memory_bytes() const { return voxel_count_ * sizeof(Voxel); }

  // Index of voxel (x, y, z) in the bricked layout.
  std::size_t index(int x, int y, int z) const {
    const std::size_t brick =
        (static_cast<std::size_t>(z >> kBrickShift) * bricks_ + (y >> kBrickShift)) * bricks_ +
        (x >> kBrickShift);
    return (brick << (3 * kBrickShift)) |
           static_cast<std::size_t>(((z & (kBrick - 1)) << (2 * kBrickShift)) |
                                    ((y & (kBrick - 1)) << kBrickShift) | (x & (kBrick - 1)));
  }
  Voxel& at(int x, int y, int z) { return voxels_.get()[index(x, y, z)]; }
  const Voxel& at(int x, int y, int z) const { return voxels_.get()[index(x, y, z)]; }
  Voxel* brick_data(int brick) { return voxels_.get() + (static_cast<std::size_t>(brick) << 9); }
  const Voxel* brick_data(int brick) const {
    return voxels_.get() + (static_cast<std::size_t>(brick) << 9);
  }

  // Bricks that have ever been integrated (for meshing and statistics).
  std::vector<std::uint8_t>& touched() { return touched_; }
  const std::vector<std::uint8_t>& touched() const { return touched_; }

  // Trilinear TSDF at grid coordinates g (voxel centres at integers). Returns false when a
  // corner is unseen or outside, so callers never interpolate towards the "empty" value.
  bool trilinear(const Eigen::Vector3f& g, float& value) const {
    const float fx = std::floor(g.x()), fy = std::floor(g.y()), fz = std::floor(g.z());
    const int x = static_cast<int>(fx), y = static_cast<int>(fy), z = static_cast<int>(fz);
    if (x < 0 || y < 0 || z < 0 || x >= resolution_ - 1 || y >= resolution_ - 1 ||
        z >= resolution_ - 1)
      return false;
    const float ax = g.x() - fx, ay = g.y() - fy, az = g.z() - fz;
    float c[8];
    if ((x & (kBrick - 1)) != kBrick - 1 && (y & (kBrick - 1)) != kBrick - 1 &&
        (z & (kBrick - 1)) != kBrick - 1) {
      // All 8 corners in one brick (2 in 3 cells): fixed offsets from the first corner.
      const Voxel* base = voxels_.get() + index(x, y, z);
      constexpr int kOffsets[8] = {0, 1, 8, 9, 64, 65, 72, 73};
      for (int i = 0; i < 8; ++i) {
        const Voxel& v = base[kOffsets[i]];
        if (v.weight() == 0) return false;
        c[i] = static_cast<float>(v.tsdf());
      }
    } else {
      for (int i = 0; i < 8; ++i) {
        const Voxel& v = at(x + (i & 1), y + ((i >> 1) & 1), z + (i >> 2));
        if (v.weight() == 0) return false;
        c[i] = static_cast<float>(v.tsdf());
      }
    }
    const float c00 = c[0] + ax * (c[1] - c[0]), c10 = c[2] + ax * (c[3] - c[2]);
    const float c01 = c[4] + ax * (c[5] - c[4]), c11 = c[6] + ax * (c[7] - c[6]);
    const float c0 = c00 + ay * (c10 - c00), c1 = c01 + ay * (c11 - c01);
    value = (c0 + az * (c1 - c0)) * (1.0f / kTsdfScale);
    return true;
  }

 private:
  int resolution_ = 0;
  int bricks_ = 0;
  float voxel_size_ = 0.0f;
  Eigen::Vector3f origin_ = Eigen::Vector3f::Zero();
  std::unique_ptr<Voxel, VoxelPagesDeleter> voxels_;
  std::size_t voxel_count_ = 0;
  std::vector<std::uint8_t> touched_;
};

}  // namespace fb
