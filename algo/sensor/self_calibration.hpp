// Self-calibration of a Kinect v1's depth-to-colour registration from ordinary frames: the
// depth image's occluding contours (the near side of a depth jump) must land on edges of the
// colour image. Estimates the registration part of RegistrationCorrection (shift and rotation)
// relative to the device's tables, with a confidence and the residual in colour pixels.
//
// Engine and objects (InfiniTAM style): SelfCalibrator accumulates per-frame edge samples
// (bounded, preallocated), estimate() searches and refines over everything accumulated.
// The depth law cannot be observed from edges; it is kept as given.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "algo/core/image.hpp"
#include "algo/core/result.hpp"
#include "algo/sensor/kinect_calibration.hpp"

namespace fb {

struct SelfCalibrationOptions {
  double search_radius_px = 28.0;   // the shift searched, each axis (units differ by up to ~20)
  double max_rotation_deg = 2.0;    // the rotation refined within this
  int max_samples_per_frame = 600;  // depth edge samples kept per frame (spread evenly)
  int max_frames = 30;              // frames kept (colour gradients, 1.2 MB each); past this,
                                    // every other stored frame is dropped and the stride doubles
  int border_px = 8;                // image border ignored in both images
  double min_jump_mm = 25.0;        // a depth edge: the neighbour is farther by this or
  double min_jump_fraction = 0.04;  //   by this fraction of the depth, whichever is larger
  // Unmeasured pixels skipped looking for the far side: past the projector's shadow beside a
  // near object, so contours facing both ways are seen (a one-sided set would confuse the
  // sensor's edge bias with a shift).
  int max_gap_px = 48;
  double min_colour_gradient = 6.0;  // grey levels per px; weaker colour edges score nothing
  int min_samples = 400;             // fewer edge samples in total: no estimate
  double ok_confidence = 0.5;        // below this the result is not to be used
};

struct SelfCalibrationResult {
  RegistrationCorrection correction;  // the full registration correction (depth law as given)
  // Residual: the median distance, along each edge sample's normal, from the registered depth
  // edge to the colour edge, after the correction (colour px). Also its 95th percentile.
  double residual_px = 0.0;
  double residual_px_p95 = 0.0;
  // How far the calibration it started from was off: |correction - given| at the image
  // centre and corners, the largest (colour px). This is what the registration health reports.
  double misregistration_px = 0.0;
  // 0..1: fraction of edge samples that agree (found a colour edge within 1.5 px after the
  // correction), times agreement of independent halves of the frames.
  double confidence = 0.0;
  double halves_disagreement_px = 0.0;  // the two halves' estimates differ by this much
  int frames = 0;
  int samples = 0;
  bool ok = false;  // confidence >= options.ok_confidence and enough samples
  std::string why;  // when !ok: what was missing, for the user
};

class SelfCalibrator {
 public:
  // `calibration`: the unit's current calibration (its depth law is used for the depth; its
  // registration correction, if any, is what misregistration_px is measured against).
  explicit SelfCalibrator(const KinectCalibration& calibration,
                          SelfCalibrationOptions options = {});

  // Adds one frame's edge samples. depth_mm is the depth camera's image under `calibration`,
  // color the colour camera's RGB image, both 640x480. Does not allocate once max_frames frames
  // have been added (buffers are reused).
  void add_frame(const DepthImage& depth_mm, const ColorImage& color);
  void clear();

  int frames() const;
  int samples() const;

  // Searches the shift on a coarse grid, then refines shift and rotation. Fails only when
  // nothing was added; a weak estimate is a result with ok = false and the reason.
  Result<SelfCalibrationResult> estimate() const;

  struct Impl;
  ~SelfCalibrator();
  SelfCalibrator(SelfCalibrator&&) noexcept;
  SelfCalibrator& operator=(SelfCalibrator&&) noexcept;

 private:
  std::unique_ptr<Impl> impl_;
};

// The calibration with `result`'s registration correction put in (depth law kept).
KinectCalibration with_registration(const KinectCalibration& calibration,
                                    const RegistrationCorrection& registration);

// Largest distance between where two registration corrections put the image centre and
// corners (colour px): the size of a registration difference in one number.
double registration_distance_px(const RegistrationCorrection& a, const RegistrationCorrection& b);

}  // namespace fb
