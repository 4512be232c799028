// Integration engine: fuses one depth image into the TSDF volume. Only voxels inside the
// truncation band along the rays of face-box pixels are visited: the rays first mark the bricks
// they cross inside the band, then only those bricks are updated (never the whole cube).
#pragma once

#include <cstdint>
#include <vector>

#include "algo/fusion/fusion_maps.hpp"
#include "algo/fusion/parallel.hpp"
#include "algo/fusion/tsdf_volume.hpp"

namespace fb {

class TsdfIntegrator {
 public:
  // Preallocates the brick marks and list for `volume`.
  void configure(const FusionOptions& options, const TsdfVolume& volume);

  // depth: level-0 depth (mm, 0 = invalid), only pixels inside `box` are used.
  // Returns the number of bricks updated.
  int integrate(const Image<float>& depth, const LevelIntrinsics& k, const PixelRect& box,
                const RigidPoseF& world_from_camera, TsdfVolume& volume, ParallelRunner& runner);

  // The widest voxel-update vector this CPU runs (8 or 4 lanes), and whether `lanes` (0 = that
  // widest) is one it runs.
  static int widest_lanes();
  static bool lanes_supported(int lanes);

 private:
  float truncation_ = 8.0f;
  int max_weight_ = 64;
  int lanes_ = 4;
  std::vector<std::uint8_t> marks_;
  std::vector<int> bricks_;
  std::vector<float> depth_lo_, depth_hi_;  // per marked brick: depth range of its rays
};

}  // namespace fb
