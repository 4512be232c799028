// Fills the colour pixels no depth pixel was splatted onto. The synthetic colour image is made
// by forward-mapping the depth camera's raster through the registration, which leaves two kinds
// of holes: thin cracks where the mapping expands, and disocclusions, where the colour camera
// sees background that the depth camera's view hides (the parallax is along +x, so they sit on
// the right of near objects). A crack takes its surface's colour; a disocclusion takes the far
// side's, never the near object's, so colour silhouettes stay where the geometry puts them.
#pragma once

#include <cstdint>

#include "algo/core/image.hpp"

namespace fb {

// `mark` is 1 where a pixel was splatted (its colour and z are valid), 0 where not. Holes are
// filled along rows, then the rest along columns (rows the mapping skipped entirely); filled
// pixels become 1. Pixels with no splatted pixel in their row or column stay 0.
void fill_color_holes(ColorImage& color, Image<float>& z, Image<std::uint8_t>& mark);

}  // namespace fb
