// Whether a traced line (salient_regions) is a groove or the image's noise, from the line itself
// (issue 40 round 7): a groove is a thin valley (or ridge) that runs straight for its length, so
// its contrast across the line's axis keeps one sign all along it; a run of noise marks has no
// axis and its contrast across one averages out. The contrast is weighed against the image's own
// noise near the line (the same second difference taken along the axis, where a groove is flat),
// so the test follows the noise where it is larger (a shadowed side, a darker skin).
#pragma once

#include <span>
#include <vector>

#include <Eigen/Core>

#include "algo/wrinkles/exemplar.hpp"

namespace fb {

struct LineEvidenceOptions {
  double offset_px = 2.0;   // the second difference's step across the line (a groove's half-width)
  int noise_margin_px = 6;  // the noise is measured over the line's box grown by this
  int extend_px = 8;        // the axis continued this far beyond each end (the continuation)
};

struct LineEvidence {
  double length_px = 0.0;     // span along the principal axis
  double thickness_px = 0.0;  // rms distance of the pixels from their centre curve, across
  int samples = 0;            // centre-curve points (one per pixel step along the axis)
  // Mean of 0.5 (D(q + o n) + D(q - o n)) - D(q) over the centre curve q (n: across the axis):
  // > 0 a valley (a dark groove), < 0 a ridge.
  double contrast = 0.0;
  double noise = 0.0;        // robust sd of the same difference along the axis, near the line
  double consistency = 0.0;  // fraction of centre points whose difference has the mean's sign
  // |contrast| / noise x sqrt(samples): how many noise sd the line's mean contrast is. Biased
  // upwards: the pixels were traced because their contrast passed a threshold.
  double score = 0.0;
  // The same difference on the axis continued beyond both ends (pixels the tracing did not pick,
  // so unbiased): its mean with the line's sign (> 0: the groove goes on), and that in noise sd
  // of the mean.
  int continuation_samples = 0;
  double continuation_contrast = 0.0;
  double continuation_score = 0.0;
};

// `detection`: the image the line was traced in; `pixels`: the line's (at least 2).
LineEvidence line_evidence(const FloatImage& detection, std::span<const Eigen::Vector2i> pixels,
                           const LineEvidenceOptions& options = {});

}  // namespace fb
