// The frame's wrinkle map weights c = P^T a (algo/wrinkles/map_weights), the one implementation
// shared by the host's DetailBlend and the booth's tracking mode: at a capture's own recipe the
// weight is 1 on that capture and 0 on the others (independent recipes), linear in a, and the
// same numbers DetailBlend::map_weights gives.
#include <gtest/gtest.h>

#include <cmath>

#include "algo/wrinkles/detail_blend.hpp"
#include "algo/wrinkles/map_weights.hpp"
#include "tests/common/allocation_counter.hpp"

namespace fb {
namespace {

// Three captures over 7 shapes, overlapping (shape 2 in two recipes) and independent.
const std::vector<std::vector<float>> kRecipes = {
    {0.9f, 0.9f, 0.3f, 0, 0, 0, 0}, {0, 0, 0.5f, 0.8f, 0.4f, 0, 0}, {0, 0, 0, 0, 0, 0.6f, 0}};

TEST(MapWeights, RecipeGivesOneOnItsCaptureAndZeroOnTheOthers) {
  auto m = MapWeights::build(kRecipes, 7);
  ASSERT_TRUE(m) << m.error().message;
  EXPECT_EQ(m->capture_count(), 3);
  EXPECT_EQ(m->shape_count(), 7);
  std::vector<float> c(3);
  for (std::size_t e = 0; e < kRecipes.size(); ++e) {
    m->apply(kRecipes[e], c);
    for (std::size_t k = 0; k < c.size(); ++k)
      EXPECT_NEAR(c[k], k == e ? 1.0f : 0.0f, 1e-5) << "recipe " << e << ", capture " << k;
  }
  // Linear: half of capture 0 plus a quarter of capture 2.
  std::vector<float> a(7);
  for (std::size_t s = 0; s < a.size(); ++s) a[s] = 0.5f * kRecipes[0][s] + 0.25f * kRecipes[2][s];
  m->apply(a, c);
  EXPECT_NEAR(c[0], 0.5f, 1e-5);
  EXPECT_NEAR(c[1], 0.0f, 1e-5);
  EXPECT_NEAR(c[2], 0.25f, 1e-5);
  // Shape 6 is in no recipe: it carries no detail. Missing weights count as 0, extra ones are
  // ignored.
  for (int e = 0; e < 3; ++e) EXPECT_EQ(m->coefficient(6, e), 0.0f);
  m->apply(std::vector<float>{0.9f, 0.9f}, c);
  EXPECT_GT(c[0], 0.5f);
  EXPECT_EQ(c[2], 0.0f);
  std::vector<float> longer = kRecipes[1];
  longer.push_back(5.0f);
  m->apply(longer, c);
  EXPECT_NEAR(c[1], 1.0f, 1e-5);
  // A frame's weights allocate nothing (the booth's tracking loop calls this per frame).
  long allocations = 0;
  {
    test::CountThreadAllocations counter;
    for (int f = 0; f < 100; ++f) m->apply(kRecipes[static_cast<std::size_t>(f % 3)], c);
    allocations = counter.count();
  }
  if (test::allocation_counting_available()) EXPECT_EQ(allocations, 0);
}

TEST(MapWeights, DependentRecipesStayFiniteAndBadInputIsRefused) {
  // Capture 1's recipe is twice capture 0's: the minimum-norm split is finite.
  const std::vector<std::vector<float>> dependent = {{0.4f, 0.2f}, {0.8f, 0.4f}};
  auto m = MapWeights::build(dependent, 2);
  ASSERT_TRUE(m);
  std::vector<float> c(2);
  m->apply(dependent[1], c);
  EXPECT_TRUE(std::isfinite(c[0]) && std::isfinite(c[1]));
  EXPECT_NEAR(c[0] * 0.4f + c[1] * 0.8f, 0.8f, 1e-4);  // W^T c reproduces a
  EXPECT_FALSE(MapWeights::build(kRecipes, 6));        // 7 weights for 6 shapes
  EXPECT_FALSE(MapWeights::build(kRecipes, 0));
  EXPECT_FALSE(MapWeights::build(std::vector<std::vector<float>>{{NAN, 0.0f}}, 2));
  auto none = MapWeights::build({}, 4);  // no capture with detail: empty weights
  ASSERT_TRUE(none);
  EXPECT_EQ(none->capture_count(), 0);
}

TEST(MapWeights, DetailBlendUsesTheSameWeights) {
  // Flat maps with one texel of detail each: the maps do not enter c.
  const int w = 8, h = 4;
  std::vector<FloatImage> d(4);
  std::vector<ColorImage> n(4);
  for (int i = 0; i < 4; ++i) {
    d[i].resize(w, h);
    n[i].resize(w, h);
    std::fill(n[i].pixels.begin(), n[i].pixels.end(), Rgb8{128, 128, 255});
    d[i].at(i, 1) = 0.1f * static_cast<float>(i + 1);
  }
  std::vector<DetailLayerView> layers;
  for (int i = 1; i < 4; ++i) layers.push_back({&d[i], &n[i]});
  auto blend = DetailBlend::build({&d[0], &n[0]}, layers, kRecipes, 7);
  ASSERT_TRUE(blend) << blend.error().message;
  auto m = MapWeights::build(kRecipes, 7);
  ASSERT_TRUE(m);
  const std::vector<float> a = {0.1f, 0.7f, 0.2f, 0.0f, 0.9f, 0.3f, 1.0f};
  std::vector<float> from_blend(3), from_weights(3);
  blend->map_weights(a, from_blend);
  m->apply(a, from_weights);
  EXPECT_EQ(from_blend, from_weights);
  for (int s = 0; s < 7; ++s)
    for (int e = 0; e < 3; ++e) EXPECT_EQ(blend->coefficient(s, e), m->coefficient(s, e));
}

}  // namespace
}  // namespace fb
