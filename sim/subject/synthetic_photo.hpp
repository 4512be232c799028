// Synthetic photographs of known faces for the 2D expression transfer (eval/bench transfer,
// tests): the synthetic camera's colour frame of a textured subject (frontal, static, no sensor
// noise) cropped around the face, with the true 68 landmarks in the crop.
#pragma once

#include <cstdint>
#include <vector>

#include "algo/core/result.hpp"
#include "algo/facemodel/face_model.hpp"
#include "algo/transfer/image_warp.hpp"

namespace fb {

struct PhotoSpec {
  std::uint64_t subject = 1;              // identity, skin tone and texture seed
  std::vector<float> expression_weights;  // one per model expression (shorter: zeros)
  int width = 311, height = 419;          // the crop (the paper's photograph size)
  double distance_mm = 500.0;             // the Kinect's nearest useful distance: largest face
};

// The crop is centred on the landmarks' centroid of the subject's neutral (the same crop for
// every expression of a subject, as two photographs from one tripod).
Result<FacePhoto> render_photo(const FaceModel& model, const PhotoSpec& spec);

// The expression recipes the 2D eval uses: name -> model expression weights.
std::vector<std::pair<std::string, std::vector<float>>> photo_expressions(const FaceModel& model);

}  // namespace fb
