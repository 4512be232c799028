// A synthetic subject's own expression shapes: the face model's, each made by the subject's own
// amount and unevenly over the face, so that no fit can read a capture as the model's generic
// expression added to the neutral (eval fit's identity part).
#pragma once

#include <cstdint>
#include <vector>

#include "algo/facemodel/face_model.hpp"

namespace fb {

// Every expression shape k of `model` times a_k * m(v): a_k from U(1 - spread, 1 + spread)
// and m(v) = 1 + spread * g(v), g a smooth field over the mean face in [-1, 1] (six Gaussian
// bumps 20-40 mm wide, either sign), both drawn from `seed`. spread 0 returns the model's shapes.
std::vector<float> personal_expression_basis(const FaceModel& model, std::uint64_t seed,
                                             double spread);

}  // namespace fb
