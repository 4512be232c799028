// Private: the kiosk's pictures. The worker shows its frames (idle preview, a take with its face
// box, tracking, self-calibration) and the fit thread the last processed capture; the HTTP
// threads copy them. Its own lock, held only to copy: readers encode outside it, since the
// take's frame loop takes it too.
#pragma once

#include <mutex>
#include <string>

#include "algo/core/frame.hpp"
#include "algo/fusion/fusion_types.hpp"

namespace fb {

class LivePreview {
 public:
  // A 2x downsample of the frame's colour image, with `box` outlined.
  void show(const RgbdFrame& frame, const FaceBox& box);
  // The same without a box.
  void show(const RgbdFrame& frame);
  ColorImage picture() const;  // empty before the first frame

  // The last processed capture's frontal colour as BMP ("" = none).
  void set_capture_bmp(std::string bmp);
  std::string capture_bmp() const;

 private:
  mutable std::mutex mutex_;
  ColorImage picture_;       // guarded by mutex_
  std::string capture_bmp_;  // guarded by mutex_
};

}  // namespace fb
