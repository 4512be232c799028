#include "algo/fusion/tsdf_volume.hpp"

#include <algorithm>
#include <string>

namespace fb {

Result<void> TsdfVolume::reset(int resolution, float size_mm, const Eigen::Vector3f& origin_mm) {
  if (resolution < kBrick || resolution % kBrick != 0 || resolution > 1024)
    return fail("TSDF resolution must be a multiple of " + std::to_string(kBrick) +
                " between 8 and 1024 (got " + std::to_string(resolution) + ")");
  if (!(size_mm > 0.0f)) return fail("TSDF volume size must be positive");
  if (resolution != resolution_) {
    resolution_ = resolution;
    bricks_ = resolution / kBrick;
    voxels_.assign(static_cast<std::size_t>(resolution) * resolution * resolution, Voxel{});
    touched_.assign(static_cast<std::size_t>(bricks_) * bricks_ * bricks_, 0);
  } else {
    clear();
  }
  voxel_size_ = size_mm / static_cast<float>(resolution);
  origin_ = origin_mm;
  return success();
}

void TsdfVolume::clear() {
  // Only touched bricks can hold data, so clearing costs what was used, not the whole cube.
  for (std::size_t b = 0; b < touched_.size(); ++b) {
    if (!touched_[b]) continue;
    std::fill_n(voxels_.data() + (b << 9), 512, Voxel{});
    touched_[b] = 0;
  }
}

}  // namespace fb
