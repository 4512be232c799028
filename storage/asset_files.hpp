// Locating and reading the committed assets (the face model). The only place that turns
// an asset path into bytes for algo/.
#pragma once

#include <filesystem>

#include "algo/core/result.hpp"
#include "algo/facemodel/face_model.hpp"

namespace fb {

// $FACEBOOTH_DATA_DIR if set, else the installed data directory, else the source tree's data/.
std::filesystem::path data_directory();

// data_directory() / "facemodel.fbfm".
std::filesystem::path default_face_model_path();

Result<FaceModel> load_face_model(const std::filesystem::path& path);
inline Result<FaceModel> load_face_model() {
  return load_face_model(default_face_model_path());
}

}  // namespace fb
