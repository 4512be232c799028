// What `track` and the lab's eval/bench track share to set a tracker up: dlib's landmark model
// and a bilinear model file for the subject's own blendshapes.
#pragma once

#include <memory>
#include <optional>
#include <string>

#include "algo/bilinear/bilinear_model.hpp"
#include "algo/core/result.hpp"
#include "algo/facemodel/face_model.hpp"
#include "algo/landmarks/landmark_detector.hpp"
#include "algo/tracking/bilinear_subject.hpp"

namespace fb::cli {

inline constexpr const char* kShapePredictor =
    "/usr/share/dlib/shape_predictor_68_face_landmarks.dat";
// dlib's detector + 68-point predictor (Debian libdlib-data), ~1 s to deserialise. An empty
// option means kShapePredictor.
Result<LandmarkDetector> load_landmark_detector(const std::string& option);

// A bilinear model file (`facebooth model build`) for the tracker: identity calibration in its
// identity space and the subject's own blendshapes. Held behind a pointer: the blendshape
// source refers to the two models.
struct BilinearSubjectModel {
  std::string path;
  BilinearModel bilinear;
  BilinearTrackingModel tracking;
  std::optional<BilinearBlendshapes> blendshapes;
  std::string describe() const;  // for reports: the file and its knobs
  // Why tracking with this model may be worse than with the face model (empty: no reason).
  std::string limitation() const;
};
// Prints "<command>: loading ..." (the file can be 700 MB) and, after it, limitation() when
// there is one.
Result<std::unique_ptr<BilinearSubjectModel>> load_bilinear_subject_model(
    const std::string& path, const FaceModel& topology, const std::string& command);

}  // namespace fb::cli
