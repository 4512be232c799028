// `export --take`'s animated glTF (issue 40 item 5, "applied in the exported animation"):
// take_ID.glb, the take's session's rig as `export --session N --format glb` writes it (ARKit's
// 52 morph targets), with one glTF animation named after the take: the 52 ARKit curves on the
// mesh's node at the take's measured frame times, the head pose on its parent node
// (storage/export/gltf_animation.hpp gives the frames). With the session's wrinkle detail the
// mesh is subdivided under the detail and every target carries its shape's own detail as
// geometry (storage/export/detail_rig.hpp), so a plain glTF viewer shows the wrinkles move with
// the expression; the per-frame map weights are in the animation's extras.
#pragma once

#include <string>

#include "algo/core/result.hpp"
#include "algo/facemodel/face_model.hpp"
#include "host/cli/detail_weights.hpp"
#include "storage/export/export_folder.hpp"
#include "storage/session_store.hpp"

namespace fb::cli {

struct TakeGlbInput {
  const SessionStore* store = nullptr;
  const TakeData* take = nullptr;
  const FaceModel* model = nullptr;  // nullptr: `model_problem` says why there is none
  std::string model_problem;
  const SessionDetailBlend* detail = nullptr;  // nullptr: no wrinkle detail to apply
};

struct TakeGlb {
  std::string file;      // take_ID.glb, empty when none was written
  std::string manifest;  // what it holds, or "none: " and why
  int vertices = 0;      // glTF vertices (seam copies included)
  bool detail = false;
};

// Writes take_ID.glb into `folder` when the take's session has a rig with ARKit-named shapes;
// otherwise says why not (a take without a session or rig is not an error: its CSV stands).
Result<TakeGlb> write_take_glb(const TakeGlbInput& in, ExportFolder& folder);

}  // namespace fb::cli
