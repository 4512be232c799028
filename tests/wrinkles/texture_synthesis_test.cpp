// The texture optimisation (section 3.3) against heights known by construction: grooves of
// known depth shaded under the booth's light, synthesised from exemplars of other grooves
// (other depths, widths and spacing), with PatchMatch and with the exact brute-force search.
#include <gtest/gtest.h>

#include <cmath>

#include "algo/core/mix64.hpp"
#include "algo/wrinkles/texture_synthesis.hpp"
#include "algo/wrinkles/wrinkle_detail.hpp"

namespace fb {
namespace {

constexpr double kMmPerPx = 1.2;  // the booth's colour camera at 0.7 m

double groove(double d_px, double depth_mm, double sigma_px) {
  return -depth_mm * std::exp(-0.5 * d_px * d_px / (sigma_px * sigma_px));
}

// Exemplar: grooves 0.15-1.1 mm deep every 9 px, horizontal (or turned a quarter).
WrinkleExemplar exemplar(bool vertical) {
  WrinkleExemplar e;
  e.name = vertical ? "grooves_90" : "grooves_0";
  e.height_mm.resize(64, 64);
  for (int y = 0; y < 64; ++y)
    for (int x = 0; x < 64; ++x) {
      const int t = vertical ? x : y, s = vertical ? y : x;
      double z = 0.0;
      for (int k = 0; k < 7; ++k) {
        const double depth = 0.15 + 0.16 * k + 0.002 * s;  // slowly deeper along the groove
        z += groove(t - (4 + 9 * k), depth, 1.0 + 0.1 * (k % 3));
      }
      e.height_mm.at(x, y) = static_cast<float>(z);
    }
  e.luminance = shade_relief(e.height_mm, kMmPerPx);
  return e;
}

struct Case {
  FloatImage height_mm, luminance;
  std::vector<PixelRect> regions;  // the wrinkles' rectangles grown by 5 px
};

// Three horizontal grooves 0.3, 0.5, 0.8 mm deep and two vertical ones 0.4 and 0.7 mm, on skin
// of another albedo, with sensor noise of 2 levels.
Case make_case() {
  Case c;
  c.height_mm.resize(180, 110);
  for (int y = 0; y < 110; ++y)
    for (int x = 0; x < 180; ++x) {
      double z = 0.0;
      if (x >= 20 && x < 100)
        z += groove(y - 25, 0.3, 1.1) + groove(y - 35, 0.5, 1.1) + groove(y - 45, 0.8, 1.2);
      if (y >= 20 && y < 90) z += groove(x - 135, 0.4, 1.1) + groove(x - 150, 0.7, 1.1);
      c.height_mm.at(x, y) = static_cast<float>(z);
    }
  SkinLight light;
  light.albedo = 0.5f;
  c.luminance = shade_relief(c.height_mm, kMmPerPx, light);
  for (std::size_t i = 0; i < c.luminance.pixels.size(); ++i) {
    const double u = (mix64(i) >> 11) * 0x1.0p-53, v = (mix64(i + 7777777) >> 11) * 0x1.0p-53;
    const double g = std::sqrt(-2.0 * std::log(u + 1e-12)) * std::cos(2 * M_PI * v);
    c.luminance.pixels[i] += static_cast<float>(2.0 / 255.0 * g);
  }
  c.regions = {PixelRect::from_size(15, 17, 90, 36), PixelRect::from_size(125, 15, 35, 80)};
  return c;
}

double mae_inside(const FloatImage& a, const FloatImage& b, const std::vector<PixelRect>& rs,
                  double* zero_baseline = nullptr) {
  double e = 0.0, z = 0.0;
  int n = 0;
  for (int y = 0; y < a.height; ++y)
    for (int x = 0; x < a.width; ++x) {
      bool in = false;
      for (const auto& r : rs) in = in || r.contains(x, y);
      if (!in) continue;
      e += std::abs(a.at(x, y) - b.at(x, y));
      z += std::abs(b.at(x, y));
      ++n;
    }
  if (zero_baseline) *zero_baseline = z / n;
  return e / n;
}

TEST(TextureSynthesis, GroovesOfKnownDepthAreRecoveredFromOtherGrooves) {
  const Case c = make_case();
  const std::vector<WrinkleExemplar> ex = {exemplar(false), exemplar(true)};
  const auto out = synthesize_wrinkles(c.luminance, c.regions, ex);
  ASSERT_TRUE(out.ok()) << out.error().message;
  double zero = 0.0;
  const double mae = mae_inside(out->height_mm, c.height_mm, c.regions, &zero);
  std::cout << "MAE " << mae << " mm (zero field " << zero << " mm)\n";
  EXPECT_LT(mae, 0.06);
  EXPECT_LT(mae, 0.4 * zero);
  // The deepest groove's floor: within 0.2 mm of its 0.8 mm.
  EXPECT_NEAR(out->height_mm.at(60, 45), -0.8, 0.2);
  // Nothing outside the regions.
  for (int y = 0; y < 110; ++y)
    for (int x = 0; x < 180; ++x)
      if (!out->domain.at(x, y)) {
        ASSERT_EQ(out->height_mm.at(x, y), 0.0f);
      }
  EXPECT_EQ(out->height_mm.at(170, 5), 0.0f);
}

TEST(TextureSynthesis, PatchMatchComesCloseToTheExactSearchWithFarFewerDistances) {
  const Case c = make_case();
  const std::vector<WrinkleExemplar> ex = {exemplar(false), exemplar(true)};
  SynthesisOptions o;
  o.em_iterations = 1;  // the gradient-only matching, where the exact search is the optimum
  const auto pm = synthesize_wrinkles(c.luminance, c.regions, ex, o);
  o.search = PatchSearch::kBruteForce;
  const auto bf = synthesize_wrinkles(c.luminance, c.regions, ex, o);
  ASSERT_TRUE(pm.ok() && bf.ok());
  std::cout << "E PatchMatch " << pm->energy.front() << " (" << pm->distance_evaluations
            << " distances), brute force " << bf->energy.front() << " (" << bf->distance_evaluations
            << ")\n";
  // Exact search is a lower bound on the gradient-only iteration's energy.
  EXPECT_LE(bf->energy.front(), pm->energy.front() * 1.0001);
  EXPECT_LT(pm->energy.front(), 1.25 * bf->energy.front());
  EXPECT_LT(pm->distance_evaluations * 20, bf->distance_evaluations);
  EXPECT_LT(mae_inside(pm->height_mm, bf->height_mm, c.regions), 0.05);
}

TEST(TextureSynthesis, EmIterationsLowerTheEnergy) {
  const Case c = make_case();
  const std::vector<WrinkleExemplar> ex = {exemplar(false), exemplar(true)};
  SynthesisOptions o;
  o.em_iterations = 5;
  const auto out = synthesize_wrinkles(c.luminance, c.regions, ex, o);
  ASSERT_TRUE(out.ok());
  // From the second iteration on E includes the height term and must not rise.
  for (std::size_t i = 2; i < out->energy.size(); ++i)
    EXPECT_LE(out->energy[i], out->energy[i - 1] * 1.02) << i;
}

TEST(TextureSynthesis, RescaledExemplarsKeepTheirDepthAndTooSmallOnesAreAnError) {
  const WrinkleExemplar e = exemplar(false);
  const auto half = rescale_exemplars(std::span(&e, 1), kMmPerPx, 2 * kMmPerPx);
  EXPECT_EQ(half.front().height_mm.width, 32);
  // A 0.15-1.1 mm groove set keeps heights of that order at half the resolution.
  float lo = 0.0f;
  for (float v : half.front().height_mm.pixels) lo = std::min(lo, v);
  EXPECT_LT(lo, -0.6f);
  WrinkleExemplar tiny;
  tiny.height_mm.resize(4, 4);
  tiny.luminance.resize(4, 4);
  const Case c = make_case();
  const auto out = synthesize_wrinkles(c.luminance, c.regions, std::span(&tiny, 1));
  ASSERT_FALSE(out.ok());
  EXPECT_NE(out.error().message.find("larger exemplars"), std::string::npos);
}

}  // namespace
}  // namespace fb

namespace fb {
namespace {

TEST(WrinkleDetail, HandGivenRegionsAreUsedAndABadDistanceIsRefused) {
  const Case c = make_case();
  const std::vector<WrinkleExemplar> ex = {exemplar(false), exemplar(true)};
  WrinkleDetailOptions o;
  o.exemplar_mm_per_px = kMmPerPx;
  o.given_regions = {PixelRect::from_size(15, 17, 90, 36)};  // the horizontal grooves only
  // 700 mm at f 583.3 px: the exemplars' own 1.2 mm per pixel.
  const auto d = wrinkle_detail(c.luminance, std::nullopt, 700.0, 700.0 / kMmPerPx, ex, o);
  ASSERT_TRUE(d.ok()) << d.error().message;
  EXPECT_NEAR(d->image_mm_per_px, kMmPerPx, 1e-9);
  EXPECT_EQ(d->synthesis.patches, 90 * 36);
  EXPECT_EQ(d->synthesis.height_mm.at(150, 50), 0.0f);  // the vertical grooves: not given
  EXPECT_LT(d->synthesis.height_mm.at(60, 45), -0.4f);  // the 0.8 mm groove's floor
  const auto bad = wrinkle_detail(c.luminance, std::nullopt, 0.0, 580.0, ex, o);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message.find("fit the face first"), std::string::npos);
}

}  // namespace
}  // namespace fb
