// The identity part's personal expressions (sim/subject/personal_expressions.hpp): each model
// shape made by its own amount and unevenly over the face, the same for a seed.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "sim/subject/personal_expressions.hpp"
#include "tests/common/test_face_model.hpp"

namespace fb {
namespace {

// Per-vertex ratio of a personal shape's displacement to the model's, over the vertices the
// model's shape moves by more than 0.5 mm.
std::vector<double> ratios(const FaceModel& model, const std::vector<float>& personal, int shape) {
  const std::size_t n = 3 * static_cast<std::size_t>(model.vertex_count);
  const float* m = model.expression_basis.data() + static_cast<std::size_t>(shape) * n;
  const float* p = personal.data() + static_cast<std::size_t>(shape) * n;
  std::vector<double> out;
  for (std::size_t v = 0; v < n / 3; ++v) {
    const double mm = std::hypot(m[3 * v], m[3 * v + 1], m[3 * v + 2]);
    if (mm > 0.5) out.push_back(std::hypot(p[3 * v], p[3 * v + 1], p[3 * v + 2]) / mm);
  }
  return out;
}

TEST(PersonalExpressions, EachShapeHasItsOwnAmountUnevenOverTheFace) {
  const FaceModel& model = test::face_model();
  EXPECT_EQ(personal_expression_basis(model, 4, 0.0), model.expression_basis);
  const auto a = personal_expression_basis(model, 4, 0.3);
  EXPECT_EQ(a, personal_expression_basis(model, 4, 0.3));
  EXPECT_NE(a, personal_expression_basis(model, 5, 0.3));
  std::vector<double> means;
  for (const char* name : {"jawOpen", "mouthSmile_L", "browInnerUp_R", "eyeBlink_L"}) {
    const auto r = ratios(model, a, model.expression_index(name));
    ASSERT_GT(r.size(), 20u) << name;
    const auto [lo, hi] = std::minmax_element(r.begin(), r.end());
    // Within (1 +- 0.3)^2, and not one factor for the whole shape.
    EXPECT_GE(*lo, 0.49 - 1e-6) << name;
    EXPECT_LE(*hi, 1.69 + 1e-6) << name;
    double sum = 0;
    for (double x : r) sum += x;
    means.push_back(sum / static_cast<double>(r.size()));
    std::printf("%s: ratio %.2f-%.2f, mean %.2f\n", name, *lo, *hi, means.back());
    EXPECT_GT(*hi / *lo, 1.05) << name;
  }
  const auto [lo, hi] = std::minmax_element(means.begin(), means.end());
  EXPECT_GT(*hi - *lo, 0.1);  // the shapes' amounts differ
}

}  // namespace
}  // namespace fb
