// Seed 002's 2D facial expression analogy (section VI): a source's expression, given as two
// photographs of one person (neutral S, expression S^e), mapped onto a photograph of another
// face (target neutral T). Steps, as the paper lists them:
//  1-3. landmarks on all three (the caller's: dlib or given), aligned by similarities, and T
//       warped piecewise-affinely so its landmarks move as S's did (image_warp.hpp);
//  4.   each image a quad mesh over its pixel grid with the luminance Y as height; S and S^e are
//       warped into the same geometry as T's warp, which makes the correspondence the identity
//       pixel for pixel (the paper resamples the source grid at the target's pixels);
//  5.   the VTC solve for the luminance: per face pixel the source's tent transformation
//       Q = w(S^e) w(S)^T (w(S) w(S)^T)^-1 (tent_mesh.hpp's tents: the four edge neighbours and
//       an apex on the normal), and the target luminance whose tents deform by the same Q's
//       third row (the x and y of a pixel do not move, so only the height equations remain,
//       with each tent's apex height free); back to RGB with the warped target's chromaticity
//       (R/Y, B/Y) plus the source's change of it (the paper keeps the target's chroma).
// The face region is inside the jaw line and above the brows; outside it the warped target
// keeps its luminance, blended over a few pixels towards the additive change S^e - S at the
// region's edge, which is also the solve's boundary condition. Mapping an expression back onto
// its own neutral photograph therefore reproduces the expression photograph inside the region.
// Pure: images and landmarks in, an image out.
#pragma once

#include "algo/core/image.hpp"
#include "algo/core/result.hpp"
#include "algo/transfer/image_warp.hpp"

namespace fb {

struct ImageTransferOptions {
  // Height of one luminance level (Y in 0..255) in pixel widths: how steep the grid surface is,
  // which sets the tents' normals and so how shading change is split between slope and height.
  double luminance_height = 1.0;
  // The jaw-line points are pulled this fraction towards the landmarks' centroid for the face
  // region (the paper moves contour points inside the face's edge), and the brow points pushed
  // out by `forehead` of their distance from it (the forehead creases with raised brows).
  double contour_inset = 0.06;
  double forehead = 0.25;
  // Outside the region, the additive luminance change fades out over this many pixels.
  double feather_px = 8.0;
  // Preconditioned conjugate gradients (Jacobi), started from the additive change T + (S^e - S).
  int max_iterations = 400;
  double tolerance = 3e-3;  // stop at residual norm <= tolerance * right-hand-side norm
};

struct ImageTransferResult {
  ColorImage image;         // the target mimicking the source's expression
  ColorImage warped;        // the target warped only (step 3; the geometric peer)
  Landmarks68 landmarks{};  // the target's landmarks in the expression, target px
  int region_pixels = 0;    // unknowns of the luminance solve
  int iterations = 0;
  double relative_residual = 0;
  double warp_ms = 0;   // alignment, triangulation and the three warps
  double solve_ms = 0;  // tents, the system and its solution, back to colour
};

// Fails on an empty image, source photographs of different sizes, a target smaller than
// 8 x 8 px, or landmarks that do not span a face.
Result<ImageTransferResult> transfer_image_expression(const FacePhoto& source_neutral,
                                                      const FacePhoto& source_expression,
                                                      const FacePhoto& target,
                                                      const ImageTransferOptions& options = {});

// One pixel's tent on a height grid (heights row-major, width x height): ring = right, down,
// left, up; apex on the area-weighted (Newell) normal of the four quads around the pixel at the
// mean ring edge length, exactly as tent_mesh.hpp builds it on a quad mesh whose quads are
// (x, y), (x + 1, y), (x + 1, y + 1), (x, y + 1). The pixel must be >= 1 px from the border.
struct GridTent {
  Eigen::Matrix<double, 3, 5> w;        // ring - v0 (4 columns), apex - v0
  Eigen::Matrix<double, 5, 3> inverse;  // w^T (w w^T)^-1
};
GridTent grid_tent(const std::vector<double>& heights, int width, int x, int y);

}  // namespace fb
