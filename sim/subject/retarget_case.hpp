// The retargeting case with known truth (eval retarget, tests/transfer): two synthetic subjects
// with personal rigs in a real session store (synthetic_rigs.hpp), subject A's take of an
// expression recipe stored as the tracker stores takes (the 52 ARKit curves, TakeWriter), and
// subject B's truth: B's own rig evaluated at the same recipe's model weights.
#pragma once

#include <filesystem>
#include <vector>

#include "algo/core/result.hpp"
#include "algo/facemodel/face_model.hpp"
#include "storage/session_store.hpp"

namespace fb {

struct RetargetCase {
  SubjectId performer = 0, target = 0;
  TakeId take = 0;
  std::vector<std::vector<float>> weights;  // per frame, one per model fitting shape (the recipe)
  RigData target_rig;
};

// Creates the store in `dir` (which must not hold one): subjects "A" (rig seed 1) and "B" (rig
// seed 2), A's take of `frames` frames of sim/camera's expressive track (jaw, smile, blinks,
// brows).
Result<RetargetCase> make_retarget_case(const std::filesystem::path& dir, const FaceModel& model,
                                        int frames);

// The same with a given recipe (`truth`, per frame one weight per model fitting shape) and the
// weights A's take stores for it (`take`: e.g. tracked from A's rendered frames).
Result<RetargetCase> make_retarget_case(const std::filesystem::path& dir, const FaceModel& model,
                                        std::vector<std::vector<float>> truth,
                                        const std::vector<std::vector<float>>& take);

// B's truth for frame `f`: its rig's neutral + sum over its shapes of the recipe's weight of the
// model shape of the same name x the shape's delta.
std::vector<float> retarget_truth(const RetargetCase& c, const FaceModel& model, int f);

}  // namespace fb
