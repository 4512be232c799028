// How far a take's raw depth frames agree with the fused surface, gathered in one reference
// view (the frontal frame the fit reads): per reference pixel, how many frames observed its
// surface and how much their residuals against the fused surface scatter. Hair, beard and
// brows (dropouts and scatter), the rims of the eyes, nostrils and the mouth slit (depth jumps)
// and grazing surfaces read low; skin reads high. The fit weights its depth term with it
// (FitTarget::confidence), because the fused surface there is an average of disagreeing
// measurements, not a measurement.
//
// Each frame's residual is taken at its own pixel against the model view fusion ray-cast at
// that frame's pose (so a steep slope, which moves a depth a lot per pixel, is not read as
// scatter), then splatted into the reference view. reset() allocates; add() does not.
#pragma once

#include <vector>

#include "algo/core/camera_model.hpp"
#include "algo/core/image.hpp"
#include "algo/core/pixel_rect.hpp"
#include "algo/core/result.hpp"
#include "algo/fusion/fusion_types.hpp"

namespace fb {

struct ViewConsistencyOptions {
  float gate_mm = 10.0f;  // larger residuals count at this size (a different surface)
  // A pixel seen by at least this fraction of the frames counts as fully observed.
  float full_seen_fraction = 0.5f;
  // Scatter (standard deviation of the observations) beyond the take's typical one that halves
  // the confidence. Relative to the typical (median) scatter of the well-observed pixels, so a
  // noisier unit or distance lowers nothing by itself: only what scatters more than the rest of
  // the face (hair reads several mm where skin reads ~1 mm) does.
  float half_confidence_scatter_mm = 2.0f;
};

class ViewConsistency {
 public:
  Result<void> reset(const PinholeIntrinsics& intrinsics,
                     const ViewConsistencyOptions& options = {});

  // One fused frame (mm, 0 = none), the fused surface seen from its pose (FaceFusion's model
  // view after process(): any pyramid level, sampled bilinearly), and its pose relative to the
  // reference camera, over `box` of the frame (empty = the whole frame).
  void add(const DepthImage& depth_mm, const Image<float>& model_depth,
           const RigidPose& reference_from_camera, const PixelRect& box);

  int frames() const { return frames_; }

  // Confidence in [0, 1] per reference pixel (0 where nothing was observed); `out` is resized.
  // Not const: it sorts a scratch buffer allocated by reset().
  void confidence(Image<float>& out);

 private:
  struct Cell {
    float sum = 0.0f;   // of the residuals (frame - fused surface), mm
    float sum2 = 0.0f;  // of their squares
    int count = 0;
  };
  PinholeIntrinsics k_;
  ViewConsistencyOptions options_;
  std::vector<Cell> cells_;
  std::vector<float> scratch_;  // variances, for the median
  int frames_ = 0;
};

}  // namespace fb
