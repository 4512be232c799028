// Ray-casting engine: renders the zero crossing of the TSDF as a depth/vertex map and normals
// for one camera pose, over the face box. Rays start just in front of a hint depth (the frame
// that was just fused) when there is one, and otherwise at the volume's entry point; they skip
// free space by the TSDF value itself and refine the crossing with trilinear interpolation.
#pragma once

#include "algo/fusion/fusion_maps.hpp"
#include "algo/fusion/parallel.hpp"
#include "algo/fusion/tsdf_volume.hpp"

namespace fb {

class RayCaster {
 public:
  void configure(const FusionOptions& options) { options_ = options; }

  // Writes out.vertices (camera frame), out.depth and out.normals inside out.box.
  // `hint` (optional, level-0 sized) holds a depth near the surface per pixel, 0 = none; the
  // previous content of out.depth is the second hint. Rays start a margin in front of the hint:
  // wider for raw depth (`hint_is_raw`) than for filtered depth. With `full_search` false, pixels
  // without any hint are left empty (the tracker's model view: it only needs surface where the
  // frame has data), which skips the long march through empty space around the head.
  void cast(const TsdfVolume& volume, const RigidPoseF& world_from_camera, const Image<float>* hint,
            bool hint_is_raw, bool full_search, MapLevel& out, ParallelRunner& runner) const;

 private:
  FusionOptions options_;
};

// Fills coarser model-view levels by subsampling level 0 (pixel u1 = pixel 2 u1).
void subsample_model_levels(ModelView& view);

}  // namespace fb
