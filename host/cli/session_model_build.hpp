// `model build --from-sessions`: the bilinear model from the rigs of a session store (issue 38,
// item 4). The store is read one subject at a time into algo/bilinear's streaming accumulators
// (streaming_decomposition.hpp): the identity Gram matrix needs ceil(N / panel) passes over the
// rigs, the core one more, and memory stays at the panel (--memory-mb) plus the core, whatever
// the number of subjects. `in_memory` stacks every rig in one dense tensor instead (the build
// before the streaming one, kept as the reference and the bench's peer; tens of subjects).
#pragma once

#include <cstddef>
#include <string>

#include "algo/core/result.hpp"
#include "algo/facemodel/face_model.hpp"
#include "host/cli/rig_support.hpp"

namespace fb::cli {

struct SessionModelOptions {
  std::string store;
  std::string sessions = "all";  // ids, comma-separated, or all
  int id_knobs = 50;
  int exp_knobs = 25;
  bool in_memory = false;
  std::size_t memory_mb = 1024;  // the identity panel's budget (streaming)
  bool progress = true;          // a bar on stderr
};

Result<BuiltModel> build_from_sessions(const FaceModel& face_model,
                                       const SessionModelOptions& options);

}  // namespace fb::cli
