#include "algo/wrinkles/wrinkle_detail.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

namespace fb {

namespace {

// The exemplars (at their own pixel size) re-shaded under `light` where they were shaded, then
// resampled to the image's pixel size.
std::vector<WrinkleExemplar> relit_exemplars(std::span<const WrinkleExemplar> exemplars,
                                             const SkinLight& light, double from_mm_per_px,
                                             double to_mm_per_px) {
  std::vector<WrinkleExemplar> relit(exemplars.begin(), exemplars.end());
  for (auto& e : relit)
    if (e.shaded) e.luminance = shade_relief(e.height_mm, from_mm_per_px, light);
  return rescale_exemplars(relit, from_mm_per_px, to_mm_per_px);
}

// The synthesis region by region, each with the exemplars shaded for its mean normal; a pixel
// in two regions belongs to the first.
Result<WrinkleSynthesis> synthesize_per_region(const FloatImage& input,
                                               std::span<const PixelRect> regions,
                                               std::span<const Eigen::Vector3f> normals,
                                               std::span<const WrinkleExemplar> exemplars,
                                               const WrinkleDetailOptions& o, double mm_per_px,
                                               const Image<std::uint8_t>* features) {
  WrinkleSynthesis out;
  out.height_mm.resize(input.width, input.height);
  std::fill(out.height_mm.pixels.begin(), out.height_mm.pixels.end(), 0.0f);
  out.domain.resize(input.width, input.height);
  std::fill(out.domain.pixels.begin(), out.domain.pixels.end(), std::uint8_t{0});
  out.energy.assign(static_cast<std::size_t>(o.synthesis.em_iterations), 0.0);
  Image<std::uint8_t> excluded = out.domain;
  for (std::size_t r = 0; r < regions.size(); ++r) {
    for (std::size_t i = 0; i < excluded.pixels.size(); ++i)
      excluded.pixels[i] = out.domain.pixels[i] || (features && features->pixels[i]);
    const std::vector<WrinkleExemplar> ex = relit_exemplars(
        exemplars, skin_light_for(normals[r], o.to_light), o.exemplar_mm_per_px, mm_per_px);
    auto s = synthesize_wrinkles(input, regions.subspan(r, 1), ex, o.synthesis, &excluded);
    if (!s) return s.failure();
    for (std::size_t i = 0; i < s->domain.pixels.size(); ++i)
      if (s->domain.pixels[i]) {
        out.domain.pixels[i] = 1;
        out.height_mm.pixels[i] = s->height_mm.pixels[i];
      }
    for (std::size_t k = 0; k < out.energy.size() && k < s->energy.size(); ++k)
      out.energy[k] += s->energy[k] * s->patches;
    out.patches += s->patches;
    out.distance_evaluations += s->distance_evaluations;
  }
  for (auto& e : out.energy) e /= std::max(1, out.patches);
  return out;
}

// Heights only this close to a kept line (WrinkleDetailOptions::keep_near_lines_px).
void keep_near_lines(WrinkleDetail& d, int r) {
  const int w = d.input.width, h = d.input.height;
  Image<std::uint8_t> near;
  near.resize(w, h);
  std::fill(near.pixels.begin(), near.pixels.end(), std::uint8_t{0});
  for (const auto& line : d.regions.lines)
    for (const auto& p : line.pixels)
      for (int y = std::max(0, p.y() - r); y <= std::min(h - 1, p.y() + r); ++y)
        for (int x = std::max(0, p.x() - r); x <= std::min(w - 1, p.x() + r); ++x)
          near.at(x, y) = 1;
  for (std::size_t i = 0; i < near.pixels.size(); ++i)
    if (!near.pixels[i]) {
      d.synthesis.height_mm.pixels[i] = 0.0f;
      d.synthesis.domain.pixels[i] = 0;
    }
}

// Heights faded with the chessboard distance to the nearest kept line (WrinkleDetailOptions::
// line_core_px / line_reach_px); regions given by hand are left as they are.
void fade_from_lines(WrinkleDetail& d, const WrinkleDetailOptions& o) {
  const int w = d.input.width, h = d.input.height, far = o.line_reach_px + 1;
  std::vector<int> dist(static_cast<std::size_t>(w) * h, far);
  for (const auto& line : d.regions.lines)
    for (const auto& p : line.pixels) dist[static_cast<std::size_t>(p.y()) * w + p.x()] = 0;
  auto relax = [&](int x, int y, int dx, int dy) {
    const int qx = x + dx, qy = y + dy;
    if (qx < 0 || qy < 0 || qx >= w || qy >= h) return;
    int& v = dist[static_cast<std::size_t>(y) * w + x];
    v = std::min(v, dist[static_cast<std::size_t>(qy) * w + qx] + 1);
  };
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (const auto& [dx, dy] : {std::pair{-1, 0}, {-1, -1}, {0, -1}, {1, -1}})
        relax(x, y, dx, dy);
  for (int y = h - 1; y >= 0; --y)
    for (int x = w - 1; x >= 0; --x)
      for (const auto& [dx, dy] : {std::pair{1, 0}, {1, 1}, {0, 1}, {-1, 1}}) relax(x, y, dx, dy);
  std::vector<std::uint8_t> given(dist.size(), 0);
  for (const auto& r : o.given_regions)
    for (int y = std::max(0, r.y0); y < std::min(h, r.y1); ++y)
      for (int x = std::max(0, r.x0); x < std::min(w, r.x1); ++x)
        given[static_cast<std::size_t>(y) * w + x] = 1;
  const float span = static_cast<float>(o.line_reach_px - o.line_core_px);
  for (std::size_t i = 0; i < dist.size(); ++i)
    if (!given[i])
      d.synthesis.height_mm.pixels[i] *=
          std::clamp(static_cast<float>(o.line_reach_px - dist[i]) / span, 0.0f, 1.0f);
}

// The largest value within r pixels along x or along y.
FloatImage max_along(const FloatImage& in, int r, bool along_x) {
  FloatImage out = in;
  const int n = along_x ? in.width : in.height;
  for (int y = 0; y < in.height; ++y)
    for (int x = 0; x < in.width; ++x) {
      const int c = along_x ? x : y;
      float m = 0.0f;
      for (int i = std::max(0, c - r); i <= std::min(n - 1, c + r); ++i)
        m = std::max(m, along_x ? in.at(i, y) : in.at(x, i));
      out.at(x, y) = m;
    }
  return out;
}

// The largest value in the (2r+1)^2 square around each pixel.
FloatImage spread_max(const FloatImage& in, int r) {
  return max_along(max_along(in, r, true), r, false);
}

// WrinkleDetailOptions' gate: the face's pixels are `face` (non-zero), or the image's.
void gate_flat(WrinkleDetail& d, const WrinkleDetailOptions& o, const RasterBuffers* face) {
  const FloatImage s = normalised_shading(d.input, o.synthesis);
  FloatImage e2 = s;
  for (auto& v : e2.pixels) v *= v;
  FloatImage e = gaussian_blur(e2, o.gate_sigma_px);
  std::vector<float> on_face;
  for (std::size_t i = 0; i < e.pixels.size(); ++i) {
    e.pixels[i] = std::sqrt(e.pixels[i]);
    if (face == nullptr || face->triangle[i] != kNoTriangle) on_face.push_back(e.pixels[i]);
  }
  if (on_face.empty()) return;
  auto mid = on_face.begin() + static_cast<long>(on_face.size() / 2);
  std::nth_element(on_face.begin(), mid, on_face.end());
  const double median = std::max(1e-6f, *mid);
  for (auto& v : e.pixels)
    v = static_cast<float>(
        std::clamp((v / median - o.gate_low) / (o.gate_high - o.gate_low), 0.0, 1.0));
  d.gate = spread_max(e, o.gate_spread_px);
  for (std::size_t i = 0; i < d.gate.pixels.size(); ++i) {
    d.synthesis.height_mm.pixels[i] *= d.gate.pixels[i];
    if (d.gate.pixels[i] <= 0.0f) d.synthesis.domain.pixels[i] = 0;
  }
}

}  // namespace

void feather_heights(FloatImage& height_mm, const Image<std::uint8_t>& domain, int px) {
  if (px <= 0) return;
  const int w = domain.width, h = domain.height;
  // City-block distance (in pixels, capped) to the nearest pixel outside the domain.
  std::vector<int> d(domain.pixels.size());
  for (std::size_t i = 0; i < d.size(); ++i) d[i] = domain.pixels[i] ? px : 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      int& v = d[static_cast<std::size_t>(y) * w + x];
      if (x > 0) v = std::min(v, d[static_cast<std::size_t>(y) * w + x - 1] + 1);
      if (y > 0) v = std::min(v, d[static_cast<std::size_t>(y - 1) * w + x] + 1);
      if (x == 0 || y == 0) v = std::min(v, 1);
    }
  for (int y = h - 1; y >= 0; --y)
    for (int x = w - 1; x >= 0; --x) {
      int& v = d[static_cast<std::size_t>(y) * w + x];
      if (x + 1 < w) v = std::min(v, d[static_cast<std::size_t>(y) * w + x + 1] + 1);
      if (y + 1 < h) v = std::min(v, d[static_cast<std::size_t>(y + 1) * w + x] + 1);
    }
  for (std::size_t i = 0; i < d.size(); ++i)
    height_mm.pixels[i] *= static_cast<float>(std::min(d[i], px)) / static_cast<float>(px);
}

Result<WrinkleDetail> wrinkle_detail(
    const FloatImage& luminance, const std::optional<std::array<Eigen::Vector2d, 68>>& landmarks,
    double face_depth_mm, double focal_px, std::span<const WrinkleExemplar> exemplars,
    const WrinkleDetailOptions& options, const WrinkleFace* face) {
  if (!(face_depth_mm > 100.0 && face_depth_mm < 5000.0 && focal_px > 10.0))
    return fail("wrinkles: the face's distance (" + std::to_string(face_depth_mm) +
                " mm) or the focal length is out of range; fit the face first");
  WrinkleDetail out;
  out.image_mm_per_px = face_depth_mm / focal_px;
  out.input = luminance;
  RasterBuffers raster;
  if (face) {
    if (face->intrinsics.width != luminance.width || face->intrinsics.height != luminance.height)
      return fail("wrinkles: the fitted mesh's camera is not the image's size");
    raster.reset(face->intrinsics.width, face->intrinsics.height);
    if (auto ok = rasterize(face->intrinsics, face->expression.vertices, face->expression.triangles,
                            {}, raster);
        !ok)
      return ok.failure();
    if (options.ratio_image && face->neutral_luminance && !face->neutral.vertices.empty()) {
      auto warped = warp_neutral(face->intrinsics, raster, face->neutral, *face->neutral_luminance,
                                 options.ratio_cubic);
      if (!warped) return warped.failure();
      out.input = ratio_image(luminance, *warped);
    }
  }
  // The mesh's openings (eyes, mouth) filled: the silhouette margin is the head's outline, not
  // the eyelids', where crow's feet begin.
  Image<std::uint8_t> skin;
  if (face) {
    skin.resize(raster.width, raster.height);
    for (std::size_t i = 0; i < skin.pixels.size(); ++i)
      skin.pixels[i] = raster.triangle[i] != kNoTriangle;
    fill_holes(skin);
  }
  out.regions = salient_regions(out.input, landmarks, options.regions, face ? &skin : nullptr);
  if (!options.given_regions.empty()) {
    if (!options.given_alongside) out.regions.regions.clear();
    out.regions.regions.insert(out.regions.regions.end(), options.given_regions.begin(),
                               options.given_regions.end());
  }
  const Image<std::uint8_t>* features =
      out.regions.features.empty() ? nullptr : &out.regions.features;
  Result<WrinkleSynthesis> synthesis = fail("no synthesis");
  if (face && options.local_light) {
    out.region_normals = region_normals(raster, face->expression, out.regions.regions);
    synthesis = synthesize_per_region(out.input, out.regions.regions, out.region_normals, exemplars,
                                      options, out.image_mm_per_px, features);
  } else {
    const std::vector<WrinkleExemplar> scaled =
        rescale_exemplars(exemplars, options.exemplar_mm_per_px, out.image_mm_per_px);
    synthesis =
        synthesize_wrinkles(out.input, out.regions.regions, scaled, options.synthesis, features);
  }
  if (!synthesis) return synthesis.failure();
  out.synthesis = std::move(*synthesis);
  if (options.keep_near_lines_px > 0) keep_near_lines(out, options.keep_near_lines_px);
  if (options.gate_high > options.gate_low) gate_flat(out, options, face ? &raster : nullptr);
  feather_heights(out.synthesis.height_mm, out.synthesis.domain, options.feather_px);
  if (options.line_reach_px > options.line_core_px && options.line_core_px >= 0 &&
      (options.given_regions.empty() || options.given_alongside))
    fade_from_lines(out, options);
  return out;
}

}  // namespace fb
