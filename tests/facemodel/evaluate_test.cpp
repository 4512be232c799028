// FaceModel::evaluate: matches a straightforward double-precision sum, honours shorter
// spans, skips zeros, and never allocates.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <vector>

#include "algo/facemodel/face_model.hpp"
#include "tests/common/allocation_counter.hpp"
#include "tests/facemodel/test_util.hpp"

namespace fb {
namespace {

std::vector<double> reference(const FaceModel& m, const std::vector<float>& c,
                              const std::vector<float>& w) {
  const std::size_t n3 = static_cast<std::size_t>(m.vertex_count) * 3;
  std::vector<double> out(m.neutral.begin(), m.neutral.end());
  for (std::size_t k = 0; k < c.size() && k < static_cast<std::size_t>(m.identity_count); ++k) {
    for (std::size_t i = 0; i < n3; ++i) out[i] += double{c[k]} * m.identity_basis[k * n3 + i];
  }
  for (std::size_t j = 0; j < w.size() && j < static_cast<std::size_t>(m.expression_count); ++j) {
    for (std::size_t i = 0; i < n3; ++i) out[i] += double{w[j]} * m.expression_basis[j * n3 + i];
  }
  return out;
}

TEST(facemodel_evaluate, MatchesReferenceSumOnTinyModel) {
  const FaceModel m = test::make_tiny_model();
  std::vector<float> out(3 * m.vertex_count);
  const std::vector<float> c = {0.5f, -1.25f};
  const std::vector<float> w = {0.0f, 1.0f, 0.3f};
  m.evaluate(c, w, out);
  const auto ref = reference(m, c, w);
  for (std::size_t i = 0; i < out.size(); ++i) EXPECT_NEAR(out[i], ref[i], 1e-5) << i;
}

TEST(facemodel_evaluate, ShorterSpansMeanZeroAndLongerAreIgnored) {
  const FaceModel m = test::make_tiny_model();
  std::vector<float> out(3 * m.vertex_count, 123.0f);
  m.evaluate({}, {}, out);
  for (std::size_t i = 0; i < out.size(); ++i) EXPECT_EQ(out[i], m.neutral[i]);

  const std::vector<float> c = {0.7f};
  const std::vector<float> w_long = {0.1f, 0.2f, 0.3f, 99.0f, 99.0f};
  m.evaluate(c, w_long, out);
  const auto ref = reference(m, c, {0.1f, 0.2f, 0.3f});
  for (std::size_t i = 0; i < out.size(); ++i) EXPECT_NEAR(out[i], ref[i], 1e-5) << i;

  // A shorter output evaluates a prefix of the vertices and writes nothing beyond it.
  std::vector<float> prefix(3 * m.face_vertex_count + 3, -1.0f);
  m.evaluate(c, w_long, std::span(prefix).first(3 * m.face_vertex_count));
  for (int i = 0; i < 3 * m.face_vertex_count; ++i) EXPECT_NEAR(prefix[i], ref[i], 1e-5) << i;
  for (std::size_t i = 3 * m.face_vertex_count; i < prefix.size(); ++i) EXPECT_EQ(prefix[i], -1.0f);
}

TEST(facemodel_evaluate, ExpressionsOnAPrecomputedBaseMatchFullEvaluation) {
  const FaceModel m = test::make_tiny_model();
  const std::vector<float> c = {0.5f, -1.25f};
  const std::vector<float> w = {0.2f, 0.0f, -0.7f};
  std::vector<float> full(3 * m.vertex_count), base(3 * m.vertex_count), out(3 * m.vertex_count);
  m.evaluate(c, w, full);
  m.evaluate(c, {}, base);
  m.evaluate_expressions(base, w, out);
  for (std::size_t i = 0; i < out.size(); ++i) EXPECT_NEAR(out[i], full[i], 1e-5) << i;
  m.evaluate_expressions(base, w, base);  // in place
  for (std::size_t i = 0; i < out.size(); ++i) EXPECT_NEAR(base[i], full[i], 1e-5) << i;
}

TEST(facemodel_evaluate, ExpressionIndexByName) {
  const FaceModel m = test::make_tiny_model();
  EXPECT_EQ(m.expression_index("jawOpen"), 0);
  EXPECT_EQ(m.expression_index("PupilDilate_L"), 2);
  EXPECT_EQ(m.expression_index("jawopen"), -1);
  EXPECT_EQ(m.expression_index(""), -1);
}

TEST(facemodel_evaluate, AssetEvaluationMatchesReferenceAndDoesNotAllocate) {
  const FaceModel& m = test::asset_model();
  ASSERT_EQ(m.vertex_count, 11248);
  std::mt19937 rng(7);
  std::normal_distribution<float> n01(0.0f, 1.0f);
  std::uniform_real_distribution<float> u01(0.0f, 1.0f);
  std::vector<float> c(m.identity_count), w(m.expression_count);
  for (auto& v : c) v = n01(rng);
  for (auto& v : w) v = u01(rng) < 0.5f ? 0.0f : u01(rng);
  std::vector<float> out(3 * m.vertex_count), out2(3 * m.vertex_count);
  const float* data_before = out.data();
  const std::size_t capacity_before = out.capacity();

  long allocations = 0;
  {
    test::CountAllocations counter;
    m.evaluate(c, w, out);
    m.evaluate_expressions(out, w, out2);
    allocations = counter.count();
  }
  if (test::allocation_counting_available()) {
    EXPECT_EQ(allocations, 0) << "evaluate() allocated";
  }
  EXPECT_EQ(out.data(), data_before);
  EXPECT_EQ(out.capacity(), capacity_before);

  const auto ref = reference(m, c, w);
  double max_diff = 0.0;
  for (std::size_t i = 0; i < out.size(); ++i)
    max_diff = std::max(max_diff, std::abs(out[i] - ref[i]));
  std::printf("evaluate vs double reference (100 identity, %d expressions): max diff %.3g mm\n",
              static_cast<int>(std::count_if(w.begin(), w.end(), [](float x) { return x != 0; })),
              max_diff);
  EXPECT_LT(max_diff, 1e-3);
}

// Prints what one evaluation costs (no assertion: timing is not a test criterion here).
TEST(facemodel_evaluate, ReportsCost) {
  const FaceModel& m = test::asset_model();
  ASSERT_GT(m.vertex_count, 0);
  std::vector<float> c(m.identity_count, 0.5f), w(m.expression_count, 0.25f);
  std::vector<float> out(3 * m.vertex_count);
  auto time_it = [&](std::span<const float> cc, std::span<const float> ww) {
    m.evaluate(cc, ww, out);  // warm-up
    constexpr int kRuns = 20;
    const auto t0 = std::chrono::steady_clock::now();
    for (int r = 0; r < kRuns; ++r) m.evaluate(cc, ww, out);
    const auto t1 = std::chrono::steady_clock::now();
    return std::chrono::duration<double, std::milli>(t1 - t0).count() / kRuns;
  };
  const double full = time_it(c, w);
  const double expr_only = time_it({}, w);
  std::vector<float> few(m.expression_count, 0.0f);
  for (int j = 0; j < 5; ++j) few[j * 7] = 0.4f;
  const double sparse = time_it({}, few);
  std::vector<float> base(3 * m.vertex_count);
  m.evaluate(c, {}, base);
  m.evaluate_expressions(base, w, out);
  const auto t0 = std::chrono::steady_clock::now();
  for (int r = 0; r < 20; ++r) m.evaluate_expressions(base, w, out);
  const double on_base =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count() / 20;
  std::printf(
      "evaluate() cost, %d vertices: all 100 identity + 57 expressions %.3f ms; 57 expressions "
      "%.3f ms; 5 expressions %.3f ms; evaluate_expressions (57) on a precomputed identity "
      "%.3f ms\n",
      m.vertex_count, full, expr_only, sparse, on_base);
}

}  // namespace
}  // namespace fb
