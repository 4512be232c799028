// Salient wrinkle regions (seed 004, section 3.2): where a face image shows wrinkles, so the
// synthesis runs only there. A wrinkle is a thin valley or ridge of shading: the luminance
// gradient changes sign across it with magnitude over a threshold (along x for a line running
// vertically, along y for one running horizontally). Marked pixels are traced into lines
// (8-connected); short lines, and lines at the mouth, lips, brows and nose (from the 68
// landmarks), are dropped; the rest are clustered into rectangles grown by a margin.
#pragma once

#include <array>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "algo/core/image.hpp"
#include "algo/core/pixel_rect.hpp"
#include "algo/wrinkles/exemplar.hpp"
#include "algo/wrinkles/line_evidence.hpp"

namespace fb {

struct SalientOptions {
  float gradient_threshold = 0.005f;  // luminance (0..1) per pixel on both sides of the line
  int min_line_px = 10;  // lines shorter than this (pores, noise) are dropped (12 to round 5)
  float feature_radius_px = 10.0f;  // lines this close to mouth/nose landmarks are dropped
  float brow_radius_px = 5.0f;      // lines this close to a brow's landmark polyline too
  int cluster_gap_px = 10;          // lines this close join one region
  int margin_px = 5;                // each region grown by this (the paper's 5 px)
  // Against a camera's noise and the skin's colour: the luminance is smoothed and divided by its
  // local mean (x 0.5, so the threshold reads as luminance on mid-grey skin) before the gradient.
  double smooth_sigma_px = 0.7;    // 0 = off
  double relative_sigma_px = 4.0;  // 0 = absolute luminance
  // With landmarks, only lines inside the face are kept: the jaw line (0-16) closed over the
  // brows (17-26) raised by forehead_fraction x the jaw's width, shrunk towards its centre by
  // outline_shrink (the silhouette and the ears are no wrinkles).
  bool inside_face_only = true;
  double forehead_fraction = 0.4;
  double outline_shrink = 0.88;
  // Lines this close (px) to the eyelids (landmarks 37-40, 43-46; not the outer corners 36 and
  // 45, where crow's feet start) are the lids' own edges.
  float eyelid_radius_px = 4.0f;
  // With landmarks, the features' pixels are left out of the synthesis (SalientRegions::
  // features): their albedo edges would read as relief. Brows: this far either side of the
  // landmark polyline; eyes: inside the contour and this far around it; nose and mouth:
  // feature_radius_px around their landmarks.
  float mask_brow_px = 6.0f;
  float mask_eye_px = 3.0f;
  // With landmarks: keep only lines in the zones where expression wrinkles form (the forehead
  // above the brows, the glabella between them, the crow's feet beyond the outer eye corners),
  // cluster each zone's lines apart, and make the regions from the zones: a forehead cluster
  // spans the zone's width (forehead lines run across it; the detector finds pieces of them),
  // a glabella or crow's-feet zone with a line is one region. No region then spans an eye or
  // a brow. Sizes are fractions of the jaw's width (landmarks 0-16). On by default (issue 40:
  // the region budgets are met only with them, docs/wrinkles.md). Off: the paper's detector
  // alone (lines anywhere on the face but the features). Without landmarks there are no zones.
  bool wrinkle_zones = true;
  // With zones: a forehead cluster spans the zone's width (round 4), or (false, round 5) its
  // lines' box + margin: the zone reaches beyond the wrinkles and the synthesis fills it.
  bool forehead_across = false;
  // With zones: forehead lines at the same height join one cluster however far apart (off:
  // recall up on subject 1, 0.63 -> 0.77, MAE and outside figures worse; docs/wrinkles.md).
  bool join_forehead_rows = false;
  // With zones: forehead clusters side by side at the same height join when the gap between them
  // is at most this (px; 0 = only cluster_gap_px).
  int forehead_row_gap_px = 0;
  // With zones: lines are traced without crossing a zone's border, so a wrinkle in a zone is not
  // joined through the sensor's noise to the face's silhouette (one component over
  // the whole face, dropped; round 6: the shadowed side's crow's feet on three of six subjects).
  // 0: off; 1: the crow's-feet zones only; 2: every zone.
  int trace_in_zones = 1;
  // With zones: a line belongs to the zone of its centroid only with most of its pixels in it.
  bool zone_majority = true;
  // With zones: in the forehead zone only sign changes along y count (its expression lines run
  // across it; a sign change along x there is noise or the skin's texture).
  bool forehead_rows_only = false;
  int min_crows_feet_px = 8;  // min_line_px in the crow's-feet zones (rays 10-15 mm)
  // The line test (line_evidence.hpp; round 7): a line from line_test_min_px long but shorter
  // than its zone's shortest is kept when its continuation beyond its ends has line_keep_score
  // or more (its contrast there in noise sd of the mean). line_test_min_px = 0: off (round 6).
  int line_test_min_px = 5;
  double line_keep_score = 5.0;
  LineEvidenceOptions evidence;
  // With a skin mask (salient_regions' `skin`): no marks within this of a pixel off the skin
  // (round 7: the local mean's 4 px reach the wall, and a forehead line ran into the
  // silhouette's marks; docs/wrinkles.md). < 0: the mask is not used (round 6).
  int silhouette_margin_px = 5;
  double crows_feet_width = 0.15;   // outwards from the outer eye corner
  double crows_feet_height = 0.18;  // centred on the corner
};

// Why a traced line was not kept (SalientRegions::dropped, for diagnosis).
enum class LineDrop { kKept, kShort, kFeature, kNoZone, kOutline, kEyelid };

struct WrinkleLine {
  std::vector<Eigen::Vector2i> pixels;
  PixelRect box;
  int zone = -1;  // with SalientOptions::wrinkle_zones: the zone of its centroid
  LineDrop drop = LineDrop::kKept;
  LineEvidence evidence;  // with SalientOptions::line_test_min_px, for lines that reached the test
  int length() const { return std::max(box.width(), box.height()); }
};

struct SalientRegions {
  Image<std::uint8_t> marked;      // 1 where the gradient changes sign over the threshold
  std::vector<WrinkleLine> lines;  // kept lines
  // Lines at least min(min_line_px, min_crows_feet_px, line_test_min_px) long that a later test
  // dropped (`drop`).
  std::vector<WrinkleLine> dropped;
  std::vector<PixelRect> regions;
  Image<std::uint8_t> features;  // 1 on brows, eyes, nose and mouth (empty without landmarks)
};

// `landmarks`: the 68 iBUG points in this image (optional); without them no line is dropped for
// lying on a feature.
// The wrinkle zones of SalientOptions::wrinkle_zones in the image: forehead, glabella, the
// image-left and image-right crow's feet.
std::vector<PixelRect> wrinkle_zones(const std::array<Eigen::Vector2d, 68>& landmarks,
                                     const SalientOptions& options);

// The image the sign changes are looked for in: the luminance smoothed and divided by its local
// mean (SalientOptions::smooth_sigma_px, relative_sigma_px).
FloatImage detection_image(const FloatImage& luminance, const SalientOptions& options);

// `skin` (optional, the image's size): 1 where the image shows the face's skin (the fitted mesh
// covers the pixel); off it, and within SalientOptions::silhouette_margin_px of a pixel off it,
// nothing is marked.
SalientRegions salient_regions(const FloatImage& luminance,
                               const std::optional<std::array<Eigen::Vector2d, 68>>& landmarks,
                               const SalientOptions& options = {},
                               const Image<std::uint8_t>* skin = nullptr);

// Sets the pixels of `mask` (0 / 1) that no path of 0s joins to the image's border: a mesh's
// openings, so that the silhouette margin above runs round the head, not round the eyes.
void fill_holes(Image<std::uint8_t>& mask);

}  // namespace fb
