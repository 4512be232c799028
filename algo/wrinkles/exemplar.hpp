// Wrinkle exemplars (seed 004, section 3.1): a pair of a height field of real skin relief (mm)
// and the gradient image of that skin as the booth's camera sees it. The pure image operations
// that make them from a scan's displacement map: blur, high-pass to the wrinkle scale,
// resampling to a pixel size, rotated copies, shading under the booth's light, gradients.
#pragma once

#include <Eigen/Core>

#include "algo/core/image.hpp"

namespace fb {

using FloatImage = Image<float>;

// Separable Gaussian blur (sigma in pixels; edges clamped).
FloatImage gaussian_blur(const FloatImage& in, double sigma_px);
// in - blur(in): keeps relief narrower than a few sigma (wrinkles), drops the face's shape.
FloatImage high_pass(const FloatImage& in, double sigma_px);
// Bilinear resampling by `scale` (output = input * scale in each side), low-passed first when
// shrinking so that fine pores do not alias into false wrinkles.
FloatImage resample(const FloatImage& in, double scale);
// A side x side square sampled from `in` turned by `degrees` about its centre (counter-clockwise
// in image coordinates, x right, y down); side must fit inside `in` at every angle
// (side <= min(width, height) / sqrt 2 does).
FloatImage rotate_square(const FloatImage& in, double degrees, int side);

// The booth's light over a patch of skin facing the camera: ambient plus a key light from the
// upper left (the synthetic camera's defaults), albedo a mid skin grey.
struct SkinLight {
  Eigen::Vector3f to_light =
      Eigen::Vector3f(-0.35f, -0.45f, 1.0f).normalized();  // z: out of the skin
  float ambient = 0.3f;
  float diffuse = 0.75f;
  float albedo = 0.7f;
};
// Luminance in [0, 1] of a height field (mm, + towards the camera) with pixels `mm_per_px` wide.
FloatImage shade_relief(const FloatImage& height_mm, double mm_per_px, const SkinLight& light = {});

// Central-difference gradients (per pixel) of an image: the exemplar's gradient image.
struct ImageGradient {
  FloatImage gx, gy;
};
ImageGradient image_gradient(const FloatImage& in);

}  // namespace fb
