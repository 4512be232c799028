// Face landmarks on the colour image: dlib's HOG face detector and the 68-point iBUG shape
// predictor (Debian libdlib-data: /usr/share/dlib/shape_predictor_68_face_landmarks.dat).
// The first frame (and any frame after the face was lost) is a full-image HOG pass. After that
// the face is tracked from the landmarks: the next frame's face box is the bounding box of the
// previous frame's 68 points mapped to a detector-style box (the offset and scale between the
// detector's box and the points' bounding box are learnt at the last real detection), and only
// the shape predictor runs, on a grey conversion of a window around the face only (~2 ms
// instead of a ~35-70 ms full-image HOG pass; the predictor is dlib's model evaluated with its
// trees packed into 16-bit leaves and prefetched: dlib's points to within a rounding step, half
// the memory and a few times faster than dlib's loop). The detector
// re-anchors on a window around the last face (resampled so that face is 96 px, four pyramid
// levels: faces of 5/6 to 1.44x its size; falling back to the full image) every
// `redetect_every` tracked frames, when the new points are implausible (bounding box size or
// position jumps, points off the image, the image under them no longer looks like the previous
// frame's face) and after reset_tracking(). Pure: the model arrives as a
// stream or bytes (the caller reads the file). dlib exceptions become errors.
#pragma once

#include <array>
#include <istream>
#include <memory>
#include <span>

#include <Eigen/Core>

#include "algo/core/image.hpp"
#include "algo/core/pixel_rect.hpp"
#include "algo/core/result.hpp"

namespace fb {

struct LandmarkDetectorOptions {
  int upsample = 0;                 // full-image pyramid upsampling (0: faces >= ~80 px)
  double track_window_scale = 2.0;  // re-detection window = last face box scaled by this
  bool track = true;                // false: every frame is a full-image detection
  // Tracking from the previous frame's points (only the shape predictor runs). false: every
  // tracked frame runs the HOG detector on the window around the last face.
  bool track_landmarks = true;
  // Re-anchor with the detector after this many frames tracked from points (0: only when the
  // points become implausible).
  int redetect_every = 10;
  // Plausibility of points tracked from the previous frame's (else the detector re-runs on this
  // frame): bounding-box width/height may change by this fraction, its centre may move by this
  // fraction of its size, every point must lie inside the image, and the grey image under the
  // new bounding box must correlate (normalised cross-correlation of a 24x24 resampling) with
  // the image under the previous frame's box by at least min_appearance_correlation (catches a
  // face that left or was covered: the predictor always returns some shape).
  double max_box_size_change = 0.15;
  double max_box_shift = 0.25;
  double min_appearance_correlation = 0.7;
};

struct DetectedLandmarks {
  // The face box the shape predictor ran on, colour image px: the detector's box, or on frames
  // tracked from points the previous frame's points mapped to a detector-style box.
  PixelRect face;
  std::array<Eigen::Vector2d, 68> points{};  // iBUG order, colour image px
  bool tracked = false;  // not a full-image pass: found in the tracking window or from points
  bool from_landmarks = false;     // the box came from the previous frame's points (no detector)
  double detection_score = 0;      // HOG margin of the last real detection (this frame unless
                                   // from_landmarks, then the detection that anchored the track)
  int frames_since_detection = 0;  // 0: the detector ran on this frame
};

class LandmarkDetector {
 public:
  // Deserialises the shape predictor (takes ~1 s for the 100 MB model).
  static Result<LandmarkDetector> create(std::istream& shape_predictor,
                                         const LandmarkDetectorOptions& options = {});
  LandmarkDetector(LandmarkDetector&&) noexcept;
  LandmarkDetector& operator=(LandmarkDetector&&) noexcept;
  ~LandmarkDetector();

  // Detects the largest face and its 68 points. "no face found" is an error result.
  Result<DetectedLandmarks> detect(const ColorImage& image);
  // Forgets the tracked face (the next call is a full-image detection).
  void reset_tracking();
  // A second detector on the same shape predictor (33 MB, read-only and shared, not copied)
  // with its own face detector and tracking state: for another thread, e.g. the device's
  // tracking mode beside its fit thread.
  LandmarkDetector share() const;

 private:
  struct State;
  explicit LandmarkDetector(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;
};

}  // namespace fb
