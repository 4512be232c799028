// The rigging input of a stored session: the fitted meshes by capture (the neutral first) and
// each capture's known weights (its guide recipe). Shared by `facebooth rig` and the tests.
//
// Policy for incomplete sessions: a session without a fitted neutral is always refused; a
// session missing other fitted expressions is refused with the list of what is missing unless
// `allow_missing` is set, in which case it is rigged from the examples that are there (the
// generic prior fills in what they do not constrain) and the gaps are reported.
#pragma once

#include <string>
#include <vector>

#include "algo/core/result.hpp"
#include "algo/facemodel/face_model.hpp"
#include "algo/guide/guide_expressions.hpp"
#include "algo/rigging/example_rigging.hpp"
#include "storage/session_store.hpp"

namespace fb::cli {

struct SessionExamples {
  SubjectId subject = 0;
  std::vector<std::string> names;           // expression per example, "neutral" first
  std::vector<int> capture_indices;         // capture index per example
  std::vector<std::vector<float>> meshes;   // 3V floats, model frame
  std::vector<std::vector<float>> weights;  // fitting_expression_count weights per example
  std::vector<std::string> missing;         // "smile (capture 2)" per missing fitted mesh
};

Result<SessionExamples> load_session_examples(const SessionStore& store, SessionId session,
                                              const FaceModel& model, const GuideSet& guide,
                                              bool allow_missing);

// A session's rig: the rigging result and the rig as the store keeps it (the model's fitting
// expression names, its triangles).
struct SessionRig {
  RigResult result;
  RigData data;
};
// Example-based rigging of loaded examples (what `rig` and `sync` do).
Result<SessionRig> rig_examples(const SessionExamples& examples, const FaceModel& model,
                                const RigOptions& options);

// The generic rig of the face model: A_0 = the model's neutral, A_j = A_0 + expression j for the
// fitting expressions (their storage lives in `storage`).
RigInput generic_rig_input(const FaceModel& model, std::vector<std::vector<float>>& storage);

}  // namespace fb::cli
