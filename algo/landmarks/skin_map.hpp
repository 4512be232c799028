// Where the depth image sees skin: per depth pixel, how alike its registered colour is to the
// face's own skin, sampled between the landmarks (cheekbones, nose). Hair, a beard and the
// brows read low. Their depth is measured off the skin (a hair cap 5-10 mm out, a beard a few
// mm, all noisy), so the fit takes it as unreliable and lets the model hold the surface there.
// The eyes, lips and brows are not skin-coloured but their depth is the surface: they read 1.
#pragma once

#include <array>
#include <span>

#include <Eigen/Core>

#include "algo/core/image.hpp"
#include "algo/core/result.hpp"
#include "algo/sensor/kinect_calibration.hpp"

namespace fb {

struct SkinMapOptions {
  // Chromaticity (r, g) further than this many robust deviations of the skin sample is not
  // skin; the deviation has a floor (a face of one even tone would otherwise reject shading).
  double chroma_sigmas = 3.0;
  double chroma_floor = 0.006;
  // Darker than the skin sample's median by more than this factor is not skin (hair, beard);
  // a shadowed cheek under a side light is 2-3x darker.
  double darker_factor = 3.5;
  // The weight falls from 1 to 0 over this many sigmas / this factor again past the limits.
  double soft_sigmas = 2.0;
  double soft_factor = 1.5;
  int median_radius_px = 2;  // median of the weights: single strands and pores do not count
  // Skin this close to a region of hair or beard reads as it does (the least weight within the
  // radius): fused depth there ramps up to the hair's surface over a few pixels.
  int hair_margin_px = 2;
};

struct SkinMapStats {
  int samples = 0;           // colour pixels in the skin sample
  double skin_fraction = 0;  // of the depth pixels with depth, weight >= 0.5
};

// `color_landmarks`: the 68 iBUG points in the colour image. The map has the depth image's
// size; pixels without depth read 0. Fails when the sample regions hold too few pixels
// (landmarks outside the colour image).
Result<Image<float>> skin_map(const Image<float>& depth_mm, const ColorImage& color,
                              const KinectRegistration& registration,
                              std::span<const Eigen::Vector2d> color_landmarks,
                              const SkinMapOptions& options = {}, SkinMapStats* stats = nullptr);

}  // namespace fb
