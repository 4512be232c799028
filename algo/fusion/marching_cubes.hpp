// Marching-cubes engine: a triangle mesh of the TSDF zero level set, over touched bricks only,
// using only cells whose 8 corners have been observed (so unseen space makes no surface).
#pragma once

#include "algo/fusion/fusion_types.hpp"
#include "algo/fusion/tsdf_volume.hpp"

namespace fb {

struct MeshOptions {
  int min_weight = 2;  // corners seen fewer times are treated as unseen (noise)
};

// Vertices are shared between neighbouring cells; normals are the TSDF gradient.
TriangleMesh extract_mesh(const TsdfVolume& volume, const MeshOptions& options = {});

}  // namespace fb
