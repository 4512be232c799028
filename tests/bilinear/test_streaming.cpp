// The streamed N-mode SVD (algo/bilinear/streaming_decomposition.hpp) against the in-memory one
// on the same tensor: Gram matrices, spectra and the truncated model agree to float round-off
// whatever the panel size (one identity, a few, all), and the accumulator refuses identities
// fed out of its order.
#include <gtest/gtest.h>

#include <random>

#include "algo/bilinear/streaming_decomposition.hpp"

namespace fb {
namespace {

// A tensor with structure (a shared mean, a few identity and expression directions) plus noise,
// so no spectrum is degenerate.
DataTensor structured_tensor(int rows, int identities, int expressions, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> n(0, 1);
  DataTensor t;
  t.rows = rows;
  t.identities = identities;
  t.expressions = expressions;
  std::vector<float> mean(static_cast<std::size_t>(rows)), id_dir(mean.size() * 3),
      exp_dir(mean.size() * 3);
  for (auto& v : mean) v = 50 * n(rng);
  for (auto& v : id_dir) v = 5 * n(rng);
  for (auto& v : exp_dir) v = 2 * n(rng);
  t.data.resize(static_cast<std::size_t>(rows) * identities * expressions);
  for (int i = 0; i < identities; ++i) {
    const float a[3] = {n(rng), n(rng), n(rng)};
    for (int e = 0; e < expressions; ++e) {
      const float b[3] = {e == 0 ? 0 : n(rng), e == 0 ? 0 : n(rng), e == 0 ? 0 : n(rng)};
      for (int x = 0; x < rows; ++x) {
        float v = mean[static_cast<std::size_t>(x)] + 0.05f * n(rng);
        for (int k = 0; k < 3; ++k)
          v += a[k] * id_dir[static_cast<std::size_t>(k * rows + x)] +
               b[k] * exp_dir[static_cast<std::size_t>(k * rows + x)] * (1 + 0.2f * a[0]);
        t.data[(static_cast<std::size_t>(e) * identities + i) * rows + x] = v;
      }
    }
  }
  return t;
}

// Identity i's expressions as the accumulators take them (slice e at e * rows).
std::vector<float> identity_slices(const DataTensor& t, int i) {
  std::vector<float> out(static_cast<std::size_t>(t.rows) * t.expressions);
  for (int e = 0; e < t.expressions; ++e)
    std::copy_n(t.data.begin() + (static_cast<std::ptrdiff_t>(e) * t.identities + i) * t.rows,
                t.rows, out.begin() + static_cast<std::ptrdiff_t>(e) * t.rows);
  return out;
}

// Max |reconstruction a - reconstruction b| over every training slice, relative to max |t|.
double model_difference(const DataTensor& t, const TruncatedTensor& a, const TruncatedTensor& b) {
  auto slice = [&](const TruncatedTensor& m, int i, int e) {
    Eigen::VectorXd out = Eigen::VectorXd::Zero(t.rows);
    for (int bb = 0; bb < m.exp_knobs; ++bb)
      for (int aa = 0; aa < m.id_knobs; ++aa)
        out +=
            Eigen::Map<const Eigen::VectorXf>(
                m.core.data() + (static_cast<std::size_t>(bb) * m.id_knobs + aa) * t.rows, t.rows)
                .cast<double>() *
            (m.identity(i, aa) * m.expression(e, bb));
    return out;
  };
  double worst = 0, scale = 0;
  for (float v : t.data) scale = std::max(scale, static_cast<double>(std::abs(v)));
  for (int i = 0; i < t.identities; ++i)
    for (int e = 0; e < t.expressions; ++e)
      worst = std::max(worst, (slice(a, i, e) - slice(b, i, e)).cwiseAbs().maxCoeff());
  return worst / scale;
}

TEST(StreamingTensor, EqualsTheInMemoryDecompositionForEveryPanelSize) {
  const DataTensor t = structured_tensor(300, 11, 6, 4);
  auto f = mode_factors(t);
  ASSERT_TRUE(f.ok());
  auto reference = truncate(t, *f, 4, 3);
  ASSERT_TRUE(reference.ok());
  const StreamShape shape{t.rows, t.identities, t.expressions};
  for (int panel : {1, 3, 4, 11, 50}) {
    SCOPED_TRACE("panel " + std::to_string(panel));
    auto gram = GramAccumulator::create(shape, panel);
    ASSERT_TRUE(gram.ok());
    int reads = 0;
    for (int i; (i = gram->next_identity()) >= 0; ++reads)
      ASSERT_TRUE(gram->add(i, identity_slices(t, i)).ok());
    const int p = std::min(panel, 11), passes = (11 + p - 1) / p;
    EXPECT_EQ(gram->passes(), passes);
    int expected_reads = 0;
    for (int k = 0; k < passes; ++k) expected_reads += std::min(11, (k + 1) * p);
    EXPECT_EQ(reads, expected_reads);
    auto sf = gram->factors();
    ASSERT_TRUE(sf.ok());
    EXPECT_LT((sf->identity_spectrum - f->identity_spectrum).norm(),
              1e-6 * f->identity_spectrum.norm());
    EXPECT_LT((sf->expression_spectrum - f->expression_spectrum).norm(),
              1e-6 * f->expression_spectrum.norm());
    auto core = CoreAccumulator::create(shape, *sf, 4, 3);
    ASSERT_TRUE(core.ok());
    for (int i = t.identities - 1; i >= 0; --i)  // any order
      ASSERT_TRUE(core->add(i, identity_slices(t, i)).ok());
    auto streamed = core->finish();
    ASSERT_TRUE(streamed.ok()) << streamed.error().message;
    const double diff = model_difference(t, *reference, *streamed);
    std::printf("panel %d: %d passes, %d reads, max relative difference %.2e\n", panel, passes,
                reads, diff);
    EXPECT_LT(diff, 1e-5);
  }
}

TEST(StreamingTensor, RefusesIdentitiesOutOfOrderAndIncompleteWork) {
  const DataTensor t = structured_tensor(20, 5, 3, 2);
  const StreamShape shape{t.rows, t.identities, t.expressions};
  auto gram = GramAccumulator::create(shape, 2);
  ASSERT_TRUE(gram.ok());
  EXPECT_FALSE(gram->factors().ok());  // nothing fed yet
  auto wrong = gram->add(1, identity_slices(t, 1));
  ASSERT_FALSE(wrong.ok());
  EXPECT_NE(wrong.error().message.find("identity 0 was wanted"), std::string::npos);
  EXPECT_FALSE(gram->add(0, std::vector<float>(7, 0.0f)).ok());  // wrong size
  auto nan = identity_slices(t, 0);
  nan[3] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_FALSE(gram->add(0, nan).ok());
  for (int i; (i = gram->next_identity()) >= 0;)
    ASSERT_TRUE(gram->add(i, identity_slices(t, i)).ok());
  auto f = gram->factors();
  ASSERT_TRUE(f.ok());
  EXPECT_FALSE(CoreAccumulator::create(shape, *f, 6, 2).ok());  // more knobs than identities
  auto core = CoreAccumulator::create(shape, *f, 2, 2);
  ASSERT_TRUE(core.ok());
  ASSERT_TRUE(core->add(0, identity_slices(t, 0)).ok());
  EXPECT_FALSE(core->add(0, identity_slices(t, 0)).ok());  // twice
  auto unfinished = core->finish();
  ASSERT_FALSE(unfinished.ok());
  EXPECT_NE(unfinished.error().message.find("missing 4 of 5"), std::string::npos);
}

}  // namespace
}  // namespace fb
