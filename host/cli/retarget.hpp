// Retargeting a stored take onto another subject's rig (issue 39 item 4, FaceWarehouse 4.3):
// the take's per-frame weights, matched to the rig's shapes by name, evaluate that rig. Shared
// by `facebooth retarget` and the lab's eval retarget.
#pragma once

#include <string>
#include <vector>

#include "algo/core/result.hpp"
#include "host/cli/commands.hpp"
#include "storage/session_store.hpp"
#include "storage/stored_data.hpp"

namespace fb::cli {

std::vector<Command> retarget_commands();  // `facebooth retarget` (retarget_commands.cpp)

// Per rig shape, the take column that drives it (-1: none, the shape stays at 0): the take's
// curve of the same name, else its ARKit curve (a take stores the tracker's 52 ARKit curves;
// a rig has the face model's names: eyeBlink_L <- eyeBlinkLeft, both browInnerUp halves <-
// browInnerUp). Fails when no shape is driven at all.
Result<std::vector<int>> take_columns_for_rig(const std::vector<std::string>& take_names,
                                              const std::vector<std::string>& rig_shapes);

// The rig's mesh for frame `f` of the take: neutral + sum_j w_j (shape_j - neutral).
std::vector<float> retarget_frame(const TakeData& take, int f, const RigData& rig,
                                  const std::vector<int>& columns);

// The rig `to` names in the store: "session:ID" (the rig serving that session,
// SessionStore::rig_for) or "subject:ID" / "ID" (that subject's newest rig).
Result<RigInfo> rig_for_target(const SessionStore& store, const std::string& to);

}  // namespace fb::cli
