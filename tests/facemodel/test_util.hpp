// Helpers shared by the face model tests.
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "algo/facemodel/face_model.hpp"
#include "tests/common/tiny_face_model.hpp"  // make_tiny_model()

namespace fb::test {

// The committed asset (FB_DATA_DIR/facemodel.fbfm), read once per process.
const std::vector<std::byte>& asset_bytes();
const FaceModel& asset_model();

// The ICT FaceKit source folder (FB_SHARED_DIR/facemodel/ict-facekit); empty if absent.
std::filesystem::path source_dir();

}  // namespace fb::test
