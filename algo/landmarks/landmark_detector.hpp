// Face landmarks on the colour image: dlib's HOG face detector and the 68-point iBUG shape
// predictor (Debian libdlib-data: /usr/share/dlib/shape_predictor_68_face_landmarks.dat).
// After the first detection the face region is tracked: the detector runs only on a window
// around the last face (a few ms instead of a full-image pass); it falls back to the full image
// when the face is lost. Pure: the model arrives as a stream or bytes (the caller reads the
// file). dlib exceptions become errors.
#pragma once

#include <array>
#include <istream>
#include <memory>
#include <span>

#include <Eigen/Core>

#include "algo/core/image.hpp"
#include "algo/core/result.hpp"

namespace fb {

struct LandmarkDetectorOptions {
  int upsample = 0;                 // full-image pyramid upsampling (0: faces >= ~80 px)
  double track_window_scale = 2.0;  // tracking window = last face box scaled by this
  bool track = true;                // false: every frame is a full-image detection
};

struct PixelBox {
  int x = 0, y = 0, width = 0, height = 0;
};

struct DetectedLandmarks {
  PixelBox face;                             // detector box, colour image px
  std::array<Eigen::Vector2d, 68> points{};  // iBUG order, colour image px
  bool tracked = false;                      // found in the tracking window
  double detection_score = 0;
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

 private:
  struct State;
  explicit LandmarkDetector(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;
};

}  // namespace fb
