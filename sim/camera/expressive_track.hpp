// The synthetic camera's anim=expressive take: a 5 s script repeated over the take, each
// expression a raised-cosine bump so every curve rises from and returns to neutral: jaw open
// (peak 0.6), smile (0.8), a blink (1.0), brows up (0.8), a second blink. What the demo tracks,
// so its Live Link CSV shows curves.
#pragma once

#include <vector>

#include "algo/facemodel/face_model.hpp"

namespace fb {

// One weight vector (model.expression_count) per frame at 30 frames/s.
std::vector<std::vector<float>> expressive_track(const FaceModel& model, int frames);

}  // namespace fb
