// Locating and reading the committed assets (the face model). The only place that turns
// an asset path into bytes for algo/.
#pragma once

#include <filesystem>
#include <optional>

#include "algo/core/result.hpp"
#include "algo/facemodel/face_model.hpp"
#include "algo/facemodel/landmark_embedding.hpp"
#include "algo/guide/guide_expressions.hpp"

namespace fb {

// $FACEBOOTH_DATA_DIR if set, else the installed data directory, else the source tree's data/.
std::filesystem::path data_directory();

// data_directory() / "facemodel.fbfm".
std::filesystem::path default_face_model_path();

Result<FaceModel> load_face_model(const std::filesystem::path& path);
inline Result<FaceModel> load_face_model() {
  return load_face_model(default_face_model_path());
}

// data_directory() / "guide_expressions.json".
std::filesystem::path default_guide_path();

// The guide expressions G0..G19, parsed and checked against `model` (every recipe's shapes
// exist in it).
Result<GuideSet> load_guide_expressions(const FaceModel& model, const std::filesystem::path& path);
inline Result<GuideSet> load_guide_expressions(const FaceModel& model) {
  return load_guide_expressions(model, default_guide_path());
}

// data_directory() / "dlib_landmark_embedding.csv".
std::filesystem::path default_landmark_embedding_path();

// dlib's landmark convention on `model` (algo/facemodel/landmark_embedding.hpp).
Result<LandmarkEmbedding> load_landmark_embedding(const FaceModel& model,
                                                  const std::filesystem::path& path);
inline Result<LandmarkEmbedding> load_landmark_embedding(const FaceModel& model) {
  return load_landmark_embedding(model, default_landmark_embedding_path());
}

// The embedding that sits beside a face model file (its directory's
// dlib_landmark_embedding.csv): nullopt when there is none, an error when it is unreadable or
// names vertices the model does not have.
Result<std::optional<LandmarkEmbedding>> landmark_embedding_beside(
    const FaceModel& model, const std::filesystem::path& model_path);

}  // namespace fb
