#include "algo/wrinkles/capture_detail.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include "algo/render/rasterizer.hpp"

namespace fb {

namespace {

float luma(const ColorImage& c, double x, double y) {
  x = std::clamp(x, 0.0, c.width - 1.001);
  y = std::clamp(y, 0.0, c.height - 1.001);
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const double ax = x - x0, ay = y - y0;
  auto l = [&](int px, int py) {
    const Rgb8 p = c.at(px, py);
    return (0.299 * p.r + 0.587 * p.g + 0.114 * p.b) / 255.0;
  };
  return static_cast<float>((1 - ay) * ((1 - ax) * l(x0, y0) + ax * l(x0 + 1, y0)) +
                            ay * ((1 - ax) * l(x0, y0 + 1) + ax * l(x0 + 1, y0 + 1)));
}

}  // namespace

Result<CaptureDetail> capture_detail(const CaptureDetailInput& in,
                                     const KinectRegistration& registration,
                                     std::span<const WrinkleExemplar> exemplars,
                                     const CaptureDetailOptions& options) {
  if (in.color == nullptr || in.color->width <= 0 || in.color->height <= 0)
    return fail("the capture has no colour frame to find wrinkles in");
  if (in.map == nullptr) return fail("wrinkle detail needs a UV layout");
  const PinholeIntrinsics k = registration.depth_intrinsics();
  const std::size_t nv = in.vertices.size() / 3;
  std::vector<Eigen::Vector3f> posed(nv);
  for (std::size_t v = 0; v < nv; ++v)
    posed[v] = in.depth_from_model
                   .apply(Eigen::Vector3d(in.vertices[3 * v], in.vertices[3 * v + 1],
                                          in.vertices[3 * v + 2]))
                   .cast<float>();
  RasterBuffers raster;
  raster.reset(k.width, k.height);
  if (auto ok = rasterize(k, posed, in.triangles, {}, raster); !ok) return ok.failure();

  CaptureDetail out;
  double face_depth = 0.0;
  for (int l = 0; l < 68; ++l) {
    const std::uint32_t v = in.landmark_vertices[static_cast<std::size_t>(l)];
    if (v >= nv) return fail("a landmark vertex is outside the fitted mesh");
    out.landmarks[static_cast<std::size_t>(l)] = k.project(posed[v].cast<double>());
    face_depth += posed[v].z() / 68.0;
  }
  if (!(face_depth > 100.0)) return fail("the fitted face is not in front of the camera");
  // The colour each depth pixel sees at the mesh's depth there; off the face, at the face's
  // mean depth (a plausible background; the region detector keeps to the face outline).
  out.luminance.resize(k.width, k.height);
  // The hand-given colour rectangles as boxes in the depth grid: min x, min y, max x, max y.
  std::vector<std::array<int, 4>> given(options.color_regions.size(), {k.width, k.height, -1, -1});
  int on_face = 0;
  for (int y = 0; y < k.height; ++y)
    for (int x = 0; x < k.width; ++x) {
      const std::size_t i = raster.index(x, y);
      const bool covered = raster.triangle[i] != kNoTriangle;
      const double z = covered ? raster.depth[i] : face_depth;
      double cx = 0.0, cy = 0.0;
      float value = 0.0f;
      if (registration.depth_to_color_interpolated(x, y, std::round(z), cx, cy)) {
        value = luma(*in.color, cx, cy), on_face += covered;
        for (std::size_t r = 0; r < given.size(); ++r)
          if (options.color_regions[r].contains(static_cast<int>(std::floor(cx)),
                                                static_cast<int>(std::floor(cy)))) {
            auto& b = given[r];
            b = {std::min(b[0], x), std::min(b[1], y), std::max(b[2], x), std::max(b[3], y)};
          }
      }
      out.luminance.at(x, y) = value;
    }
  if (on_face < 1000)
    return fail("the fitted mesh covers too little of the colour frame (" +
                std::to_string(on_face) + " pixels); refit the capture");
  WrinkleDetailOptions detail_options = options.detail;
  for (std::size_t r = 0; r < given.size(); ++r) {
    const auto& b = given[r];
    const PixelRect& c = options.color_regions[r];
    if (b[2] < b[0])
      return fail("the region " + std::to_string(c.x0) + "," + std::to_string(c.y0) + "," +
                  std::to_string(c.width()) + "," + std::to_string(c.height()) +
                  " of the colour frame is not seen by the depth camera; give a rectangle on "
                  "the face");
    detail_options.given_regions.push_back(
        PixelRect::from_size(b[0], b[1], b[2] - b[0] + 1, b[3] - b[1] + 1));
  }
  WrinkleFace face;
  face.intrinsics = k;
  face.expression = {posed, in.triangles};
  if (in.neutral != nullptr && in.neutral->camera_vertices.size() == posed.size()) {
    face.neutral = {in.neutral->camera_vertices, in.triangles};
    face.neutral_luminance = &in.neutral->luminance;
  }
  auto detail = wrinkle_detail(out.luminance, out.landmarks, face_depth, k.fx, exemplars,
                               detail_options, &face);
  if (!detail) return detail.failure();
  out.detail = std::move(*detail);
  feather_heights(out.detail.synthesis.height_mm, out.detail.synthesis.domain, options.feather_px);
  HeightView view;
  view.height_mm = &out.detail.synthesis.height_mm;
  view.domain = &out.detail.synthesis.domain;
  view.camera_from_model = in.depth_from_model;
  view.intrinsics = k;
  auto maps = detail_maps(*in.map, in.uvs, in.triangle_uvs, in.vertices, in.triangles, view);
  if (!maps) return maps.failure();
  out.maps = std::move(*maps);
  out.camera_vertices = std::move(posed);
  return out;
}

}  // namespace fb
