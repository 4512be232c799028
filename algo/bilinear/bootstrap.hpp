// The bootstrap bilinear model: since no database of rigged subjects exists on the first day,
// the tensor is built from the face model itself. Subject i = the model's neutral + a random
// identity c_i (N(0, 1) per sigma-scaled mode); its 54 expressions are the neutral and the 53
// fitting expression shapes applied to it, B_ij = face(c_i, e_j), exactly the personal rigs the
// rigging would produce from perfect data. The tensor is linear in the model's bases, so it is
// kept factored (tensor_decomposition.hpp), never as 150 x 54 dense meshes.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "algo/bilinear/bilinear_model.hpp"
#include "algo/bilinear/tensor_decomposition.hpp"
#include "algo/facemodel/face_model.hpp"

namespace fb {

// `count` identities of model.identity_count N(0, 1) coefficients each, from `seed`.
std::vector<std::vector<float>> draw_identities(const FaceModel& model, int count,
                                                std::uint64_t seed);

// basis = [neutral, identity modes, fitting expression shapes] (3V x (1 + I + E')), and
// a(i, e) = [1, c_i, onehot(e)] with expression 0 the neutral.
FactoredTensor bootstrap_tensor(const FaceModel& model,
                                const std::vector<std::vector<float>>& identities);

// "neutral" then the model's fitting expression names.
std::vector<std::string> bootstrap_expression_names(const FaceModel& model);

// Packs a truncation with the face model's topology into a model (metadata: JSON text).
BilinearModel make_bilinear_model(const TruncatedTensor& truncated, const FaceModel& topology,
                                  std::vector<std::string> expression_names, std::string metadata);

}  // namespace fb
