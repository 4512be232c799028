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
#include <map>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "algo/core/result.hpp"
#include "algo/facemodel/face_model.hpp"

namespace fb {

struct LandmarkEmbedding {
  using Vertices = std::array<std::uint32_t, 68>;
  Vertices vertices{};  // any expression without its own entry
  // Per guide expression (by name): dlib moves some points with the expression (the inner lips
  // sit on the lips' inner rim when the mouth opens, on the lips' contact line when it closes).
  std::map<std::string, Vertices, std::less<>> by_expression;

  // The vertices for a capture of `expression` (the guide's name; "" = unknown).
  const Vertices& for_expression(std::string_view expression) const;
};

// The model's own convention (what a fit uses without an embedding).
LandmarkEmbedding model_landmark_embedding(const FaceModel& model);

// Text form: a header line "landmark,vertex" (or "landmark,vertex,expression") and 68 rows
// "i,v" for every expression; rows "i,v,NAME" override landmark i for expression NAME. '#'
// lines are comments. Refused when a vertex is outside the model or a row is missing.
Result<LandmarkEmbedding> parse_landmark_embedding(std::string_view text, const FaceModel& model);
std::string format_landmark_embedding(const LandmarkEmbedding& embedding, std::string_view comment);

// Learning: `hits[l]` are the model vertices dlib's point l fell on, one per render (each
// subject's own mesh, same topology). Per landmark the hits are placed on the mean face, their
// coordinate-wise median taken (robust to a failed detection) and snapped to the nearest
// vertex of the face region. Landmarks with fewer than `min_hits` hits, and the contour, keep
// the model's vertex.
using LandmarkHits = std::array<std::vector<std::uint32_t>, 68>;
LandmarkEmbedding learn_landmark_embedding(const FaceModel& model, const LandmarkHits& hits,
                                           int min_hits = 5);

// The same per guide expression: the pooled hits give the default; each expression's own hits
// (at least `min_hits`) give its entry, kept only where it differs from the default.
LandmarkEmbedding learn_landmark_embedding(const FaceModel& model,
                                           const std::map<std::string, LandmarkHits>& hits,
                                           int min_hits = 5);

}  // namespace fb
