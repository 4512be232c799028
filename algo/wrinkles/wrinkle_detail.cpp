#include "algo/wrinkles/wrinkle_detail.hpp"

#include <algorithm>

namespace fb {

Result<WrinkleDetail> wrinkle_detail(
    const FloatImage& luminance, const std::optional<std::array<Eigen::Vector2d, 68>>& landmarks,
    double face_depth_mm, double focal_px, std::span<const WrinkleExemplar> exemplars,
    const WrinkleDetailOptions& options) {
  if (!(face_depth_mm > 100.0 && face_depth_mm < 5000.0 && focal_px > 10.0))
    return fail("wrinkles: the face's distance (" + std::to_string(face_depth_mm) +
                " mm) or the focal length is out of range; fit the face first");
  WrinkleDetail out;
  out.image_mm_per_px = face_depth_mm / focal_px;
  out.regions = salient_regions(luminance, landmarks, options.regions);
  if (!options.given_regions.empty()) {
    if (!options.given_alongside) out.regions.regions.clear();
    out.regions.regions.insert(out.regions.regions.end(), options.given_regions.begin(),
                               options.given_regions.end());
  }
  const std::vector<WrinkleExemplar> scaled =
      rescale_exemplars(exemplars, options.exemplar_mm_per_px, out.image_mm_per_px);
  auto synthesis =
      synthesize_wrinkles(luminance, out.regions.regions, scaled, options.synthesis,
                          out.regions.features.empty() ? nullptr : &out.regions.features);
  if (!synthesis) return synthesis.failure();
  out.synthesis = std::move(*synthesis);
  if (options.keep_near_lines_px > 0) {
    const int r = options.keep_near_lines_px, w = luminance.width, h = luminance.height;
    Image<std::uint8_t> near;
    near.resize(w, h);
    std::fill(near.pixels.begin(), near.pixels.end(), std::uint8_t{0});
    for (const auto& line : out.regions.lines)
      for (const auto& p : line.pixels)
        for (int y = std::max(0, p.y() - r); y <= std::min(h - 1, p.y() + r); ++y)
          for (int x = std::max(0, p.x() - r); x <= std::min(w - 1, p.x() + r); ++x)
            near.at(x, y) = 1;
    for (std::size_t i = 0; i < near.pixels.size(); ++i)
      if (!near.pixels[i]) {
        out.synthesis.height_mm.pixels[i] = 0.0f;
        out.synthesis.domain.pixels[i] = 0;
      }
  }
  return out;
}

}  // namespace fb
