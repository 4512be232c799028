// `facebooth track --drive subject:ID --drive-out DIR`: a live track driving another subject's
// stored rig (issue 39 item 4, FaceWarehouse 4.3): every tracked frame's 52 ARKit curves,
// matched to the rig's shapes by name as `facebooth retarget` matches a stored take's
// (take_columns_for_rig), evaluate that rig, and the mesh is written as the frame arrives.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "algo/core/result.hpp"
#include "algo/tracking/arkit.hpp"
#include "storage/session_store.hpp"
#include "storage/stored_data.hpp"

namespace fb::cli {

struct RigDrive {
  RigData rig;
  RigId rig_id = 0;
  std::vector<int> columns;  // per rig shape, its ARKit curve (-1: none)
  std::filesystem::path dir;
  bool ply = false;
  long long written = 0;
};

// `to`: subject:ID, session:ID or ID in `store`; `format`: obj or ply. Fails when --drive-out
// exists or the rig has no shape an ARKit curve drives.
Result<RigDrive> open_rig_drive(const SessionStore& store, const std::string& to,
                                const std::filesystem::path& dir, const std::string& format);

// The rig's mesh for the frame's weights: neutral + sum w (shape - neutral).
std::vector<float> drive_mesh(const RigDrive& drive, const ArkitFrame& frame);

// Writes DIR/frame_INDEX.obj|ply (INDEX = the camera frame's index, 6 digits).
Result<void> drive_frame(RigDrive& drive, const ArkitFrame& frame);

}  // namespace fb::cli
