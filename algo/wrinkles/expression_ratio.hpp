// The expression ratio image and the per-region light (issue 40 round 5, docs/wrinkles.md): what
// the fitted meshes add to one expression's colour frame before the wrinkle synthesis.
//
// Ratio image: the subject's neutral frame warped into the expression's image through the two
// fitted meshes (one topology: per pixel the expression mesh's triangle and barycentrics, the
// same point on the neutral mesh, projected into the neutral's image), and the expression's
// luminance divided by it. The skin's albedo (freckles, blotches) and the neutral's own lines
// cancel; what the expression adds (its wrinkles, some slow shading) stays.
//
// Per-region light: the exemplars are shaded for skin facing the camera; a forehead turned up
// into the key light shows a groove as one dark line rather than a dark-bright pair. The light is
// expressed in the tangent frame of a region's mean normal (from the fitted mesh) so the
// exemplars can be re-shaded as that skin would look.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "algo/core/camera_model.hpp"
#include "algo/core/result.hpp"
#include "algo/render/rasterizer.hpp"
#include "algo/wrinkles/exemplar.hpp"
#include "algo/wrinkles/salient_regions.hpp"

namespace fb {

// A fitted mesh in a camera: vertices in the camera frame (mm; x right, y down, z forward).
struct MeshInCamera {
  std::span<const Eigen::Vector3f> vertices;
  std::span<const std::uint32_t> triangles;
};

// Per pixel of `raster` (the expression mesh drawn through `k`): the neutral image's luminance
// at the same point of the skin (bilinear), 0 off the mesh or off the neutral's image. Both
// images through the same camera model `k`; `neutral` has the expression mesh's topology.
// `cubic`: Catmull-Rom instead of bilinear (less smoothing of the neutral's freckles than the
// expression's own pixels have).
Result<FloatImage> warp_neutral(const PinholeIntrinsics& k, const RasterBuffers& raster,
                                const MeshInCamera& neutral, const FloatImage& neutral_luminance,
                                bool cubic = false);

// luminance / warped x 0.5 (mid-grey skin) where warped > min_warped, the luminance elsewhere
// (off the mesh: the detector and synthesis keep to the face anyway).
FloatImage ratio_image(const FloatImage& luminance, const FloatImage& warped,
                       float min_warped = 0.02f);

// The mean unit normal (camera frame, towards the camera) of the mesh's triangles seen in each
// region; (0, 0, -1) for a region the mesh does not cover.
std::vector<Eigen::Vector3f> region_normals(const RasterBuffers& raster, const MeshInCamera& mesh,
                                            std::span<const PixelRect> regions);

// `base` with its light direction re-expressed for a skin patch whose normal is `normal`
// (camera frame), the key light coming from `to_light` (camera frame). SkinLight's frame is x
// right, y down (image axes projected onto the patch), z out of the skin; for a patch facing
// the camera, to_light (lx, ly, lz) becomes (lx, ly, -lz).
SkinLight skin_light_for(const Eigen::Vector3f& normal, const Eigen::Vector3f& to_light,
                         const SkinLight& base = {});

}  // namespace fb
