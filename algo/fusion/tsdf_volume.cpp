#include "algo/fusion/tsdf_volume.hpp"

#include <sys/mman.h>

#include <algorithm>
#include <string>

namespace fb {

void VoxelPagesDeleter::operator()(Voxel* pages) const {
  if (pages != nullptr) ::munmap(pages, bytes);
}

Result<void> TsdfVolume::reset(int resolution, float size_mm, const Eigen::Vector3f& origin_mm) {
  if (resolution < kBrick || resolution % kBrick != 0 || resolution > 1024)
    return fail("TSDF resolution must be a multiple of " + std::to_string(kBrick) +
                " between 8 and 1024 (got " + std::to_string(resolution) + ")");
  if (!(size_mm > 0.0f)) return fail("TSDF volume size must be positive");
  if (resolution != resolution_) {
    const std::size_t count = static_cast<std::size_t>(resolution) * resolution * resolution;
    voxels_.reset();
    void* pages = ::mmap(nullptr, count * sizeof(Voxel), PROT_READ | PROT_WRITE,
                         MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (pages == MAP_FAILED) {
      resolution_ = 0;
      voxel_count_ = 0;
      return fail("cannot map " + std::to_string(count * sizeof(Voxel) >> 20) +
                  " MB for a TSDF volume of " + std::to_string(resolution) +
                  "^3 voxels (use a smaller resolution)");
    }
    voxels_ = std::unique_ptr<Voxel, VoxelPagesDeleter>(static_cast<Voxel*>(pages),
                                                        VoxelPagesDeleter{count * sizeof(Voxel)});
    voxel_count_ = count;
    resolution_ = resolution;
    bricks_ = resolution / kBrick;
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
    std::fill_n(voxels_.get() + (b << 9), 512, Voxel{});
    touched_[b] = 0;
  }
}

}  // namespace fb
