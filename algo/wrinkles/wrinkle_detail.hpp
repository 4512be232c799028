// One expression's wrinkle detail (seed 004, sections 3.2-3.3 together): the salient regions of
// its colour frame, then the texture optimisation inside them. What `facebooth wrinkles` runs
// per expression and what `facebooth-lab eval/bench wrinkles` score and time.
#pragma once

#include <array>
#include <optional>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "algo/wrinkles/salient_regions.hpp"
#include "algo/wrinkles/texture_synthesis.hpp"

namespace fb {

struct WrinkleDetailOptions {
  SalientOptions regions;
  SynthesisOptions synthesis;
  double exemplar_mm_per_px = 0.25;  // the exemplars' pixel size (data/wrinkle_exemplars)
  // Heights are kept only this close (px, square neighbourhood) to a kept wrinkle line, the rest
  // of each region set to 0 (the paper's "neighbourhood around the detected wrinkles, 5 pixels"
  // read as around the lines; the regions' boxes still give the synthesis its context).
  // 0 = keep the whole regions.
  int keep_near_lines_px = 0;
  // Regions given by hand (the paper's user rectangles, margin included): used instead of the
  // detected ones (the features are still left out), or beside them with `given_alongside`.
  std::vector<PixelRectI> given_regions;
  bool given_alongside = false;
};

struct WrinkleDetail {
  SalientRegions regions;
  WrinkleSynthesis synthesis;  // height_mm: 0 outside the regions
  double image_mm_per_px = 0.0;
};

// `luminance`: the frontal colour frame's luma (0..1); `landmarks`: its 68 points (optional);
// `face_depth_mm`: the face's distance, which with `focal_px` gives the skin's pixel size the
// exemplars are resampled to.
Result<WrinkleDetail> wrinkle_detail(
    const FloatImage& luminance, const std::optional<std::array<Eigen::Vector2d, 68>>& landmarks,
    double face_depth_mm, double focal_px, std::span<const WrinkleExemplar> exemplars,
    const WrinkleDetailOptions& options = {});

}  // namespace fb
