// Helpers shared by the face model tests.
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "algo/facemodel/face_model.hpp"

namespace fb::test {

// A small but complete model (5 vertices, 2 identity modes, 3 expressions) with
// deterministic contents, for format and evaluate tests that must not depend on the asset.
FaceModel make_tiny_model();

// The committed asset (FB_DATA_DIR/facemodel.fbfm), read once per process.
const std::vector<std::byte>& asset_bytes();
const FaceModel& asset_model();

// The ICT FaceKit source folder (FB_SHARED_DIR/facemodel/ict-facekit); empty if absent.
std::filesystem::path source_dir();

}  // namespace fb::test
