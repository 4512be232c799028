// A small, pure software rasterizer for the synthetic camera: pinhole projection, z-buffer with
// perspective-correct depth, optional backface culling, and per-pixel triangle id plus
// perspective-correct barycentrics so callers can interpolate any vertex attribute (normals,
// albedo) themselves. No files, no threads, no allocation once the buffers have their size.
#pragma once

#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "algo/core/camera_model.hpp"
#include "algo/core/result.hpp"

namespace fb {

inline constexpr std::int32_t kNoTriangle = -1;

// One render target. `depth` holds camera-frame z in millimetres (+infinity where nothing was
// drawn); `triangle` the id of the visible triangle (kNoTriangle where nothing was drawn);
// `bary1`/`bary2` the perspective-correct barycentric weights of the triangle's second and third
// vertex at the pixel centre (the first one is 1 - bary1 - bary2).
struct RasterBuffers {
  int width = 0;
  int height = 0;
  std::vector<float> depth;
  std::vector<std::int32_t> triangle;
  std::vector<float> bary1;
  std::vector<float> bary2;

  // Sizes the buffers (allocates only when the size changes) and clears them.
  void reset(int w, int h);
  std::size_t index(int x, int y) const {
    return static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + x;
  }
  bool covered(int x, int y) const { return triangle[index(x, y)] != kNoTriangle; }
};

struct RasterOptions {
  // Drop triangles whose front side (counter-clockwise vertex order seen from outside, the OBJ
  // convention) faces away from the camera.
  bool cull_backfaces = true;
  // Triangles with any vertex closer than this are skipped rather than clipped: the synthetic
  // scenes keep everything well in front of the camera, so clipping code would never run.
  float near_mm = 10.0f;
  // Added to the triangle index written to `RasterBuffers::triangle`, so several meshes can be
  // drawn into one target and told apart.
  std::int32_t triangle_id_offset = 0;
};

// Draws `triangles` (3 indices each into `vertices`, camera frame, mm; x right, y down, z
// forward) into `target`, which must already have its size (call reset() first). Pixel (x, y)
// is sampled at its centre, which the intrinsics place at u = x, v = y (OpenCV convention).
// Fails only on an index out of range (nothing is drawn then).
Result<void> rasterize(const PinholeIntrinsics& intrinsics,
                       std::span<const Eigen::Vector3f> vertices,
                       std::span<const std::uint32_t> triangles, const RasterOptions& options,
                       RasterBuffers& target);

}  // namespace fb
