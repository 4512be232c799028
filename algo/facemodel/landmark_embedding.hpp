// Which mesh vertex each of a landmark detector's 68 points marks. dlib's shape predictor was
// trained on iBUG 300-W annotations, whose convention differs from the face model's own
// landmark vertices (brows on their upper edge, eye and lip points on the visible rims): fitted
// with the model's vertices, dlib's points pull the mesh 2-3 px sideways on every face
// (docs/tuning.md). The embedding is learned in the laboratory (`facebooth-lab landmarks
// embed`: dlib on textured renders of subjects the evaluations do not use) and shipped as
// data/dlib_landmark_embedding.csv. The contour (0-16) keeps the model's vertices: the fit
// slides those along the silhouette.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "algo/core/result.hpp"
#include "algo/facemodel/face_model.hpp"

namespace fb {

struct LandmarkEmbedding {
  std::array<std::uint32_t, 68> vertices{};
};

// The model's own convention (what a fit uses without an embedding).
LandmarkEmbedding model_landmark_embedding(const FaceModel& model);

// Text form: a header line "landmark,vertex" and 68 rows "i,v" in order; '#' lines are
// comments. Refused when a vertex is outside the model or a row is missing.
Result<LandmarkEmbedding> parse_landmark_embedding(std::string_view text, const FaceModel& model);
std::string format_landmark_embedding(const LandmarkEmbedding& embedding, std::string_view comment);

// Learning: `hits[l]` are the model vertices dlib's point l fell on, one per render (each
// subject's own mesh, same topology). Per landmark the hits are placed on the mean face, their
// coordinate-wise median taken (robust to a failed detection) and snapped to the nearest
// vertex of the face region. Landmarks with fewer than `min_hits` hits, and the contour, keep
// the model's vertex.
LandmarkEmbedding learn_landmark_embedding(const FaceModel& model,
                                           const std::array<std::vector<std::uint32_t>, 68>& hits,
                                           int min_hits = 5);

}  // namespace fb
