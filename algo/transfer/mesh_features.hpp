// Feature points for a mesh that has none (seed 002 section V; issue 39 item 2): the mesh drawn
// frontally by the project's rasterizer, shaded grey, so that a 2D landmark detector (dlib in
// algo/landmarks, run by the caller) can find the 68 iBUG points on the picture; each point is
// then carried back onto the surface through the pixel's triangle and barycentrics.
// The mesh is expected in the face model's axes: +y up, the face looking along +z.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "algo/core/camera_model.hpp"
#include "algo/core/image.hpp"
#include "algo/core/result.hpp"
#include "algo/render/rasterizer.hpp"
#include "algo/transfer/tent_mesh.hpp"

namespace fb {

struct FrontalRender {
  ColorImage image;
  RasterBuffers raster;  // the triangle and barycentrics under every pixel
  PinholeIntrinsics camera;
};

// The mesh seen from +z: its front (the vertices within `depth_mm` of the point nearest to the
// viewer) framed into `side` x `side` pixels with a margin, lit from the front and above.
FrontalRender render_frontal(const Points& points, std::span<const std::uint32_t> triangles,
                             int side = 480, double depth_mm = 90);

// Each pixel position's point on the surface (the visible triangle under it; a point that falls
// just off the silhouette takes the nearest covered pixel within `search_px`). Fails when a
// point has no surface near it.
Result<Points> back_project(const FrontalRender& render, const Points& points,
                            std::span<const std::uint32_t> triangles,
                            std::span<const Eigen::Vector2d> pixels, int search_px = 8);

}  // namespace fb
