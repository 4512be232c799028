// The geometric half of seed 002's 2D expression analogy (section VI, steps 2-3 and VI-B): the
// three photographs are aligned by their 68 iBUG landmarks (a 2D similarity), the source's
// landmark motion (neutral -> expression) is carried into the target's frame, and images are
// warped piecewise-affinely over a triangulation of the landmarks and the target image's border.
// Pure: images in, images out.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "algo/core/image.hpp"
#include "algo/core/pixel_rect.hpp"
#include "algo/core/result.hpp"

namespace fb {

using Landmarks68 = std::array<Eigen::Vector2d, 68>;  // iBUG order, image px

// A photograph and its 68 landmarks.
struct FacePhoto {
  ColorImage image;
  Landmarks68 points{};
};

// y = scale * R * x + t in the plane.
struct Similarity2d {
  Eigen::Matrix2d linear = Eigen::Matrix2d::Identity();  // scale * R
  Eigen::Vector2d translation = Eigen::Vector2d::Zero();
  Eigen::Vector2d apply(const Eigen::Vector2d& p) const { return linear * p + translation; }
  Similarity2d inverse() const;
};

// Least-squares similarity taking `from[i]` onto `to[i]` over the listed indices (all when
// empty). Fails when the points are (near) coincident.
Result<Similarity2d> align_similarity_2d(const Landmarks68& from, const Landmarks68& to,
                                         const std::vector<int>& subset = {});

// The landmarks the expression hardly moves (eye corners, the contour's ends): the source
// expression photograph is aligned to the source neutral by these, so that head motion between the
// two photographs is not taken for expression.
const std::vector<int>& rigid_landmarks();

// A mesh over the target image: the landmarks plus points on the image border, triangulated
// once (Delaunay of the target's neutral landmarks); every photograph gets its own positions of
// those control points.
struct WarpMesh {
  std::vector<std::uint32_t> triangles;  // 3 per triangle, into the control points
  int landmark_count = 68;               // control points 0..67 are the landmarks
};

// Positions of the control points in one image: the landmarks, then the border points (the
// target image's border brought into that image by `image_from_target`).
std::vector<Eigen::Vector2d> control_points(const Landmarks68& landmarks, int target_width,
                                            int target_height,
                                            const Similarity2d& image_from_target);

WarpMesh warp_mesh(const std::vector<Eigen::Vector2d>& target_controls);

// Where each output pixel comes from: per pixel its triangle (-1: none, identity fallback) and
// two barycentric weights in the output's control positions.
struct WarpMap {
  int width = 0, height = 0;
  std::vector<std::int32_t> triangle;
  std::vector<float> b1, b2;
};

// Rasterises `mesh` at `output_controls` (the geometry the output shows). Folded triangles
// (orientation flipped against the mesh's) are skipped; pixels they leave uncovered keep -1.
WarpMap warp_map(const WarpMesh& mesh, const std::vector<Eigen::Vector2d>& output_controls,
                 int width, int height);

// RGB as floats (0..255), planar per channel, for sampling and the luminance solve.
struct FloatRgb {
  int width = 0, height = 0;
  std::vector<float> r, g, b;
};

// The output image: `source` sampled (bilinear, clamped) at each output pixel's point, which is
// the pixel's barycentric position over `source_controls`; pixels with no triangle sample the
// source at `fallback`(pixel). Only the pixels in `box` are computed (the rest are 0).
FloatRgb warp_image(const ColorImage& source, const WarpMesh& mesh, const WarpMap& map,
                    const std::vector<Eigen::Vector2d>& source_controls,
                    const Similarity2d& fallback, const PixelRect& box = kAllPixels);

ColorImage to_color_image(const FloatRgb& image);

// The three photographs brought into one geometry: the target's landmarks moved by the source's
// expression (in the target's frame), and the transforms between the frames.
struct ExpressionGeometry {
  Landmarks68 target_expression{};      // target px
  Similarity2d source_from_target;      // target px -> source neutral px
  Similarity2d expression_from_source;  // source neutral px -> source expression px
};

Result<ExpressionGeometry> expression_geometry(const Landmarks68& source_neutral,
                                               const Landmarks68& source_expression,
                                               const Landmarks68& target);

// The peer of the VTC transfer and its first step (section VI-B): the target photograph warped
// piecewise-affinely so that its landmarks move as the source's did. Fails on images of
// different sizes between the source pair, or an empty image.
Result<ColorImage> warp_expression(const FacePhoto& source_neutral,
                                   const FacePhoto& source_expression, const FacePhoto& target);

}  // namespace fb
