// Section 4 on the maps (algo/wrinkles/detail_blend): blendshape detail solved from captures
// with known recipes; blending at weights 0 gives the neutral's maps, at a capture's own recipe
// that capture's maps, and the blend is linear in between.
#include <gtest/gtest.h>

#include <cmath>

#include "algo/wrinkles/detail_blend.hpp"

namespace fb {
namespace {

struct Layer {
  FloatImage d;
  ColorImage n;
  DetailLayerView view() const { return {&d, &n}; }
};

// A groove of `depth` mm along row `row` (+-3 texels) with its normal map (slope across rows).
Layer groove(int w, int h, int row, float depth) {
  Layer l;
  l.d.resize(w, h);
  l.n.resize(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const float t = static_cast<float>(y - row);
      const float v = std::abs(t) <= 3.0f ? -depth * std::exp(-0.5f * t * t / 2.0f) : 0.0f;
      const float slope = std::abs(t) <= 3.0f ? -v * t / 2.0f / 4.0f : 0.0f;  // dv per texel
      l.d.at(x, y) = v;
      l.n.at(x, y) = v == 0.0f ? Rgb8{128, 128, 255} : DetailBlend::normal_byte(0.0f, -slope);
    }
  return l;
}

TEST(DetailBlend, WeightsZeroGiveNeutralAndRecipesGiveTheirCapture) {
  const int w = 64, h = 48, shapes = 6;
  const Layer neutral = groove(w, h, 10, 0.1f);
  const std::vector<Layer> captures = {groove(w, h, 25, 0.8f), groove(w, h, 38, 0.5f)};
  // Recipes over 6 shapes; capture 0 moves shapes 0-2, capture 1 shapes 2-4, shape 5 none.
  const std::vector<std::vector<float>> recipes = {{0.9f, 0.9f, 0.3f, 0, 0, 0},
                                                   {0, 0, 0.5f, 0.8f, 0.4f, 0}};
  std::vector<DetailLayerView> views;
  for (const auto& c : captures) views.push_back(c.view());
  auto blend = DetailBlend::build(neutral.view(), views, recipes, shapes);
  ASSERT_TRUE(blend) << blend.error().message;
  EXPECT_EQ(blend->detailed_shapes(), 5);  // shape 5 is in no recipe
  // Support: the three grooves' 7 rows each.
  EXPECT_EQ(blend->support().size(), static_cast<std::size_t>(3 * 7 * w));
  BlendedDetail out;
  blend->prepare(out);
  const auto* data = out.channels.data();
  auto max_errors = [&](const Layer& want, double& disp, int& normal) {
    disp = 0.0;
    normal = 0;
    for (std::size_t i = 0; i < want.d.pixels.size(); ++i) {
      disp = std::max(
          disp, static_cast<double>(std::abs(out.displacement_mm.pixels[i] - want.d.pixels[i])));
      const Rgb8 a = out.normal_map.pixels[i], b = want.n.pixels[i];
      normal = std::max({normal, std::abs(a.r - b.r), std::abs(a.g - b.g), std::abs(a.b - b.b)});
    }
  };
  double disp = 0.0;
  int normal = 0;
  blend->apply(std::vector<float>(shapes, 0.0f), out);
  max_errors(neutral, disp, normal);
  std::printf("weights 0: max displacement error %.2e mm, normal %d levels\n", disp, normal);
  EXPECT_LT(disp, 1e-6);
  EXPECT_LE(normal, 1);
  for (std::size_t e = 0; e < captures.size(); ++e) {
    blend->apply(recipes[e], out);
    max_errors(captures[e], disp, normal);
    std::printf("capture %zu's recipe: max displacement error %.2e mm, normal %d levels\n", e, disp,
                normal);
    EXPECT_LT(disp, 0.005);  // the layers' 8-bit steps: <= half of 0.8 mm / 127 each
    EXPECT_LE(normal, 2);
  }
  // Halfway to capture 0: the displacement halfway between the neutral's and capture 0's.
  std::vector<float> half = recipes[0];
  for (auto& a : half) a *= 0.5f;
  blend->apply(half, out);
  double worst = 0.0;
  for (std::size_t i = 0; i < neutral.d.pixels.size(); ++i)
    worst = std::max(worst, static_cast<double>(
                                std::abs(out.displacement_mm.pixels[i] -
                                         0.5f * (neutral.d.pixels[i] + captures[0].d.pixels[i]))));
  EXPECT_LT(worst, 0.005);
  EXPECT_EQ(out.channels.data(), data);  // no reallocation per frame
}

TEST(DetailBlend, RefusesMapsOfDifferentSizes) {
  const Layer neutral = groove(32, 32, 10, 0.1f);
  const Layer other = groove(16, 32, 10, 0.1f);
  const std::vector<DetailLayerView> views = {other.view()};
  const std::vector<std::vector<float>> recipes = {{1.0f}};
  EXPECT_FALSE(DetailBlend::build(neutral.view(), views, recipes, 1));
}

}  // namespace
}  // namespace fb
