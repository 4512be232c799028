#include "sim/subject/personal_expressions.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Core>

#include "sim/camera/hashed_draws.hpp"

namespace fb {
namespace {

constexpr std::uint64_t kStreamAmount = 11, kStreamField = 12;

// g(v) over the mean face: bumps on random face vertices, normalised to a peak of 1.
std::vector<float> smooth_field(const FaceModel& model, std::uint64_t seed) {
  const int V = model.vertex_count;
  std::vector<float> mean(static_cast<std::size_t>(3 * V));
  model.evaluate({}, {}, mean);
  auto at = [&](int v) { return Eigen::Vector3f(mean[3 * v], mean[3 * v + 1], mean[3 * v + 2]); };
  std::vector<float> g(static_cast<std::size_t>(V), 0.0f);
  constexpr int kBumps = 6;
  for (int k = 0; k < kBumps; ++k) {
    const int centre = std::min(
        model.face_vertex_count - 1,
        static_cast<int>(hashed_uniform(seed, kStreamField, 4 * k) * model.face_vertex_count));
    const float r =
        20.0f + 20.0f * static_cast<float>(hashed_uniform(seed, kStreamField, 4 * k + 1));
    const float a = hashed_uniform(seed, kStreamField, 4 * k + 2) < 0.5 ? -1.0f : 1.0f;
    const Eigen::Vector3f c = at(centre);
    for (int v = 0; v < V; ++v) {
      const float d2 = (at(v) - c).squaredNorm();
      if (d2 < 9.0f * r * r) g[v] += a * std::exp(-d2 / (2.0f * r * r));
    }
  }
  float peak = 0.0f;
  for (float x : g) peak = std::max(peak, std::abs(x));
  if (peak > 0.0f)
    for (float& x : g) x /= peak;
  return g;
}

}  // namespace

std::vector<float> personal_expression_basis(const FaceModel& model, std::uint64_t seed,
                                             double spread) {
  std::vector<float> basis = model.expression_basis;
  if (spread <= 0.0) return basis;
  const auto V = static_cast<std::size_t>(model.vertex_count);
  const std::vector<float> g = smooth_field(model, seed);
  for (int k = 0; k < model.expression_count; ++k) {
    const double a = 1.0 + spread * (2.0 * hashed_uniform(seed, kStreamAmount, k) - 1.0);
    float* shape = basis.data() + static_cast<std::size_t>(k) * 3 * V;
    for (std::size_t v = 0; v < V; ++v) {
      const auto m = static_cast<float>(a * (1.0 + spread * g[v]));
      for (int c = 0; c < 3; ++c) shape[3 * v + c] *= m;
    }
  }
  return basis;
}

}  // namespace fb
