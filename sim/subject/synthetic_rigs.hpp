// Synthetic subjects' rigs for a session store (bench model, tests/bilinear): a random face-model
// identity with each fitting shape at its own amplitude, so the rigs are personal and the tensor
// they make is not the face model's factored one.
#pragma once

#include <cstdint>
#include <string>

#include "algo/core/result.hpp"
#include "algo/facemodel/face_model.hpp"
#include "storage/session_store.hpp"

namespace fb {

// Subject `seed`'s rig: identity N(0, 1) per mode, every fitting shape at an amplitude drawn
// from U(0.6, 1.4) (std::mt19937_64 seeded with `seed`).
RigData synthetic_rig(const FaceModel& model, std::uint64_t seed);

// Adds subject `name` with a one-capture session ("neutral") and synthetic_rig(model, seed)
// built from it.
Result<void> add_synthetic_rig_subject(SessionStore& store, const FaceModel& model,
                                       const std::string& name, std::uint64_t seed);

}  // namespace fb
