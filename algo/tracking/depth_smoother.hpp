// The tracker's depth preprocessing: a ring of the last frames, their temporal mean per pixel
// (wrinkle paper 4.1) in the face box, then an edge-aware spatial mean, in the spirit of the
// bilateral filter KinectFusion applies to raw depth before ICP. Pure: data in, data out.
#pragma once

#include <vector>

#include "algo/core/image.hpp"
#include "algo/core/pixel_rect.hpp"
#include "algo/tracking/tracker_options.hpp"

namespace fb {

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

// The temporal + spatial smoothing of one face box. Every buffer is allocated once.
class DepthSmoother {
 public:
  void allocate(const DepthSmootherOptions& options, int width, int height);
  // Forgets the frames (the next one starts a new ring).
  void clear() { ring_count_ = 0; }
  // Copies the newest frame into the ring (callers reuse theirs).
  void push(const DepthImage& depth);
  // Smooths `rect` of the newest frame `depth` (the one pushed last) into smoothed(); returns
  // the valid pixels there (depth within [min_depth_mm, max_depth_mm]). Pixels outside `rect`
  // keep what an earlier frame left.
  int smooth(const DepthImage& depth, const PixelRect& rect);
  const Image<float>& smoothed() const { return smoothed_; }

 private:
  int smooth_temporally(const DepthImage& depth, const PixelRect& rect);
  void smooth_spatially(const PixelRect& rect);

  DepthSmootherOptions options_;
  int width_ = 0;
  std::vector<DepthImage> ring_;
  int ring_count_ = 0;
  int ring_head_ = -1;
  Image<float> smoothed_;
  Image<float> spatial_scratch_;  // the spatial pass's output before it replaces smoothed_
};

}  // namespace fb
