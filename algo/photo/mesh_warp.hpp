// The photograph warped by a mesh (FaceWarehouse 4.1 and 4.3: the image re-rendered with its
// own colours after the fitted face mesh changed). Each vertex has a position in the photo
// (the fitted mesh projected) and a target position (the changed mesh projected with the same
// pose); the output is the photo sampled backwards:
//
//  - pixels the target mesh covers (z-buffered, nearest surface wins) take the photo's colour
//    at the same barycentric point of the source triangle: a piecewise-affine warp;
//  - the mouth opening (inside the target's inner-lip polygon and not covered by the lips) is
//    the mouth's cavity colour: a photo of a closed mouth has no teeth or tongue to show;
//  - every other pixel (background, hair, neck, the eye openings) moves by the displacement of
//    its nearest covered pixel, faded to zero over `falloff` x the face's size, so the
//    background stays where it was, no seam shows at the face's edge, and a chin that moves up
//    pulls the neck after it instead of leaving its old outline behind.
//
// Pure: images in memory, no I/O.
#pragma once

#include <cstdint>
#include <span>

#include <Eigen/Core>

#include "algo/core/image.hpp"
#include "algo/core/result.hpp"

namespace fb {

struct MeshWarpInput {
  std::span<const std::uint32_t> triangles;  // 3 per triangle, indices into source/target
  std::span<const Eigen::Vector2f> source;   // per vertex: where it is in the photo (px)
  std::span<const Eigen::Vector3f> target;   // per vertex: x, y (px) and depth (larger = farther)
  std::span<const Eigen::Vector2f> mouth;    // the target's inner-lip polygon (may be empty)
};

struct MeshWarpOptions {
  double falloff = 0.35;  // the displacement outside the face fades out over this x face size
  Rgb8 mouth_color{58, 22, 24};
  // false: no cavity (an edit of a closed mouth; the gap between the lips is filled around).
  bool mouth_cavity = true;
};

struct MeshWarpStats {
  int covered_pixels = 0;   // pixels drawn from the mesh
  int mouth_pixels = 0;     // pixels of the mouth opening
  double max_shift_px = 0;  // largest displacement of a covered pixel
};

// Fails when the inputs disagree in size or a triangle indexes past the vertices.
Result<ColorImage> warp_photo(const ColorImage& photo, const MeshWarpInput& input,
                              const MeshWarpOptions& options = {}, MeshWarpStats* stats = nullptr);

}  // namespace fb
