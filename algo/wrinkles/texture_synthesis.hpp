// Wrinkle texture optimisation (seed 004, section 3.3): a height field (mm) for the salient
// regions of a face image, synthesised from exemplar pairs (shading, height) by the EM texture
// optimisation of Kwatra et al. with the input's gradients held fixed. Each patch of the input
// is matched to the exemplar patch nearest in
//   E = sum_p |g_p - g'_q|^2 + lambda |h_p - h_q|^2
// (g: the input's gradients, never altered; h: the synthesised heights; g', h: the exemplar's),
// then every pixel's height is the weighted mean of what the overlapping matches put there.
// Patch search is PatchMatch (propagation + random search over all exemplars) or brute force
// (the exact nearest patch; the bench's peer). Only pixels inside the regions get heights; the
// rest stay 0.
//
// Gradients are taken of the luminance divided by its local mean (a Gaussian of
// normalise_sigma_px), in levels of a mid-grey 8-bit image: skin tone, exposure and the face's
// slow shading drop out, and the paper's lambda = 10 (gradients in 8-bit levels, heights in mm)
// keeps its balance.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "algo/core/result.hpp"
#include "algo/wrinkles/exemplar.hpp"
#include "algo/wrinkles/salient_regions.hpp"

namespace fb {

// One exemplar pair at a pixel size: the skin's relief (mm, + towards the camera) and its
// shading as the booth's camera sees it (luminance 0..1), the same size.
struct WrinkleExemplar {
  std::string name;
  FloatImage height_mm;
  FloatImage luminance;
  // The luminance is shade_relief() of the heights (the shipped set): it may be re-shaded for
  // another light (WrinkleDetailOptions::local_light). False for a photograph (user exemplars).
  bool shaded = true;
};

// The exemplars resampled from their pixel size to the input image's (both images alike, the
// shading low-passed when shrinking as a camera pixel integrates it).
std::vector<WrinkleExemplar> rescale_exemplars(std::span<const WrinkleExemplar> exemplars,
                                               double from_mm_per_px, double to_mm_per_px);

enum class PatchSearch { kPatchMatch, kBruteForce };

struct SynthesisOptions {
  int patch_radius = 2;             // 5 x 5 patches
  double lambda = 10.0;             // weight of the height channel (the paper's)
  int em_iterations = 4;            // the first matches gradients only (no heights yet)
  int patchmatch_passes = 4;        // per EM iteration, alternating scan order
  double normalise_sigma_px = 4.0;  // local mean the luminance is divided by
  double feature_levels = 128.0;    // gradient units: levels of a mid-grey 8-bit image
  double robust_exponent = -0.6;    // E-step weight |d|^(r - 2), r = 0.8 (Kwatra et al.)
  double shading_weight = 4.0;      // the normalised shading itself as a third channel
  PatchSearch search = PatchSearch::kPatchMatch;
  std::uint64_t seed = 1;
};

struct WrinkleSynthesis {
  FloatImage height_mm;        // the input's size; 0 outside the regions
  Image<std::uint8_t> domain;  // 1 inside the regions
  int patches = 0;             // patch centres (= domain pixels)
  std::vector<double> energy;  // mean E per patch after each EM iteration's search
  std::int64_t distance_evaluations = 0;
};

// The luminance divided by its local mean, minus 1, in levels (see the header comment).
FloatImage normalised_shading(const FloatImage& luminance, const SynthesisOptions& options);
// The gradient features of a luminance image: the gradients of normalised_shading().
ImageGradient wrinkle_features(const FloatImage& luminance, const SynthesisOptions& options);

// `luminance`: the face image (0..1); `regions`: where to synthesise (salient regions, margin
// included); `exemplars` at the input's pixel size; `excluded` (optional, the input's size): pixels
// never synthesised (the features). Fails when no exemplar is larger than a
// patch or the options are out of range.
Result<WrinkleSynthesis> synthesize_wrinkles(const FloatImage& luminance,
                                             std::span<const PixelRect> regions,
                                             std::span<const WrinkleExemplar> exemplars,
                                             const SynthesisOptions& options = {},
                                             const Image<std::uint8_t>* excluded = nullptr);

}  // namespace fb
