// One expression's wrinkle detail (seed 004, sections 3.2-3.3 together): the salient regions of
// its colour frame, then the texture optimisation inside them. What `facebooth wrinkles` runs
// per expression and what `facebooth-lab eval/bench wrinkles` score and time.
#pragma once

#include <array>
#include <optional>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "algo/wrinkles/expression_ratio.hpp"
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
  // Heights fall to 0 where the input shows no more relief than the face's noise (round 5):
  // r = the local rms (a Gaussian of gate_sigma_px) of the normalised shading over its median on
  // the face, mapped linearly from gate_low (0) to gate_high (1), spread by gate_spread_px (the
  // largest value in that square), multiplies the heights; the synthesis domain keeps only
  // pixels where it is > 0. gate_high <= gate_low: off.
  double gate_sigma_px = 1.5;
  double gate_low = 0.0, gate_high = 0.0;
  int gate_spread_px = 5;
  // Heights faded to 0 over this many pixels towards the synthesis domain's edge (round 5: the
  // regions' margin, so heights reach little beyond the lines found; 0 = off).
  int feather_px = 5;
  // Heights faded with the distance to the nearest kept line (detected regions only): full up to
  // line_core_px, 0 from line_reach_px (px, chessboard distance; reach <= core: off). Round 6:
  // a line's marks reach 1-2 px past its groove (smoothing, central differences), so the box's
  // margin held heights beyond the relief; within 4 px of a line is inside the paper's 5 px.
  int line_core_px = 1, line_reach_px = 4;
  // Regions given by hand (the paper's user rectangles, margin included): used instead of the
  // detected ones (the features are still left out), or beside them with `given_alongside`.
  std::vector<PixelRect> given_regions;
  bool given_alongside = false;
  // With a WrinkleFace (issue 40 round 5): the expression ratio image (the luminance divided by
  // the neutral warped through the meshes) before the regions and the features, and the
  // exemplars re-shaded per region for the region's mean normal under `to_light`.
  bool ratio_image = true;
  bool ratio_cubic = false;  // warp_neutral's Catmull-Rom
  // Off by default: on the lab's grooves it raised the MAE (0.140 -> 0.144 mean over subjects
  // 1-6, docs/wrinkles.md round 5).
  bool local_light = false;
  // The booth's key light, camera frame (x right, y down, z forward): from the upper left, in
  // front of the face, as SkinLight's default for skin facing the camera.
  Eigen::Vector3f to_light = Eigen::Vector3f(-0.35f, -0.45f, -1.0f).normalized();
};

// What the fitted meshes give one expression's synthesis (all optional but the expression's
// mesh): its mesh in the image's camera, and the subject's neutral (its luminance through the
// same camera model and its fitted mesh, the same topology, in that camera).
struct WrinkleFace {
  PinholeIntrinsics intrinsics;
  MeshInCamera expression;
  MeshInCamera neutral;  // empty: no ratio image
  const FloatImage* neutral_luminance = nullptr;
};

struct WrinkleDetail {
  FloatImage input;  // what the regions and the synthesis saw: the ratio image or the luminance
  SalientRegions regions;
  std::vector<Eigen::Vector3f> region_normals;  // with local_light, per region (camera frame)
  FloatImage gate;             // with the gate: the factor the heights were multiplied by
  WrinkleSynthesis synthesis;  // height_mm: 0 outside the regions
  double image_mm_per_px = 0.0;
};

// Heights faded to 0 over `px` pixels towards the edge of the synthesis domain (chamfer
// distance), so the maps show no step where a region's box or a feature mask ends.
void feather_heights(FloatImage& height_mm, const Image<std::uint8_t>& domain, int px);

// `luminance`: the frontal colour frame's luma (0..1); `landmarks`: its 68 points (optional);
// `face_depth_mm`: the face's distance, which with `focal_px` gives the skin's pixel size the
// exemplars are resampled to; `face` (optional): the fitted meshes, for the ratio image and the
// per-region light. `exemplars` at options.exemplar_mm_per_px.
Result<WrinkleDetail> wrinkle_detail(
    const FloatImage& luminance, const std::optional<std::array<Eigen::Vector2d, 68>>& landmarks,
    double face_depth_mm, double focal_px, std::span<const WrinkleExemplar> exemplars,
    const WrinkleDetailOptions& options = {}, const WrinkleFace* face = nullptr);

}  // namespace fb
