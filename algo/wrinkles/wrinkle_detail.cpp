#include "algo/wrinkles/wrinkle_detail.hpp"

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
  const std::vector<WrinkleExemplar> scaled =
      rescale_exemplars(exemplars, options.exemplar_mm_per_px, out.image_mm_per_px);
  auto synthesis =
      synthesize_wrinkles(luminance, out.regions.regions, scaled, options.synthesis,
                          out.regions.features.empty() ? nullptr : &out.regions.features);
  if (!synthesis) return synthesis.failure();
  out.synthesis = std::move(*synthesis);
  return out;
}

}  // namespace fb
