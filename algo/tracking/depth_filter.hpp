// Spatial depth pre-filter of the tracker: an edge-aware mean, in the spirit of the bilateral
// filter KinectFusion applies to raw depth before ICP. Pure: data in, data out.
#pragma once

#include "algo/core/image.hpp"

namespace fb {

// Half-open pixel rectangle [x0, x1) x [y0, y1).
struct PixelRect {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  bool empty() const { return x1 <= x0 || y1 <= y0; }
};

struct EdgeAwareMeanOptions {
  int radius_px = 1;      // (2r+1)^2 window
  float range_mm = 3.0f;  // neighbours further than this from the centre pixel do not count
};

// out(x, y) = mean of in over the window's pixels d > 0 with |d - in(x, y)| < range_mm, for the
// pixels of `rect` at least radius_px inside it; invalid pixels (0) stay 0. Depth edges (eye
// and mouth openings, the silhouette, an occluder's rim) therefore stay sharp, while on smooth
// skin independent per-pixel noise drops by up to 2r+1. `in` and `out` have the same size and
// are distinct; pixels of `out` outside that interior are not written.
void edge_aware_mean(const Image<float>& in, const PixelRect& rect,
                     const EdgeAwareMeanOptions& options, Image<float>& out);

}  // namespace fb
