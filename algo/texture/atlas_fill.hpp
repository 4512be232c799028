// Fills the texels no view saw. On the surface first (mesh_fill): unseen parts of the mesh (the
// back of the head, under the chin) take colours spread over the mesh from the seen ones, so the
// two sides of a UV seam, which are one surface, get one colour. Then the texels outside every
// UV triangle (the gutters between charts) by push-pull over an image pyramid, so texture
// filtering at a chart's border does not bleed in black.
#pragma once

#include <cstdint>
#include <span>

#include <Eigen/Core>

#include "algo/core/image.hpp"
#include "algo/texture/texel_map.hpp"

namespace fb {

// `color`: linear 0..255 per channel; `known`: > 0 where the texel was observed. Texels with
// known == 0 get a smooth blend of the observed ones around them.
void push_pull_fill(Image<Eigen::Vector3f>& color, const Image<float>& known);

// Texels of the layout's triangles with known == 0 get the colour interpolated from per-vertex
// colours: the observed texels' colours averaged onto their triangles' corners, then spread to
// unseen vertices along mesh edges (each unseen vertex the mean of its seen or already filled
// neighbours, breadth first). Sets known = 1 on the texels it fills.
void mesh_fill(Image<Eigen::Vector3f>& color, Image<float>& known, const TexelMap& map,
               std::span<const std::uint32_t> triangles, std::size_t vertex_count);

}  // namespace fb
