// The guide expressions G0..G19 of a capture session (FaceWarehouse section 3.1): the neutral
// face and the 19 FaceWarehouse expressions, each a named weight recipe over the face model's
// ARKit-style expression shapes. The recipes are data (data/guide_expressions.json); this
// module parses the text (the file is read outside algo/) and turns recipes into weights and
// meshes. The weights are also the "known weights" example-based rigging needs.
#pragma once

#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "algo/core/result.hpp"
#include "algo/facemodel/face_model.hpp"

namespace fb {

struct GuideExpression {
  int id = 0;                                          // 0 = neutral, 1..19 in FaceWarehouse order
  std::string name;                                    // machine name, e.g. "mouth_stretch"
  std::string label;                                   // kiosk text, e.g. "Mouth stretch"
  std::vector<std::pair<std::string, float>> weights;  // model expression name -> weight
};

struct GuideSet {
  std::vector<GuideExpression> expressions;  // sorted by id, ids 0..N-1 without gaps

  // Index of an expression by machine name, or -1.
  int find(std::string_view name) const;
};

// Parses the JSON text of data/guide_expressions.json. Checks the format tag, that ids run
// 0..N-1, that names are unique, that id 0 is the neutral (no weights) and that weights are
// finite and in [0, 1]. Does not check shape names (that needs a model; see below).
Result<GuideSet> parse_guide_expressions(std::string_view json_text);

// Checks that every referenced shape exists in `model` (errors name the recipe and the shape).
Result<void> validate_guide(const GuideSet& guide, const FaceModel& model);

// One weight per model expression for a recipe (unknown names are an error).
Result<std::vector<float>> guide_weights(const GuideExpression& expression, const FaceModel& model);

// The guide mesh G_i: the model's mean identity with the recipe's weights (3 * vertex_count
// floats, model frame, mm).
Result<std::vector<float>> guide_mesh(const GuideExpression& expression, const FaceModel& model);

// One mesh per recipe part, in the recipe's order: the mean identity with that part's weight
// alone (G0 plus the part). The expression fit scales each to how the person made it.
Result<std::vector<std::vector<float>>> guide_part_meshes(const GuideExpression& expression,
                                                          const FaceModel& model);

}  // namespace fb
