#include "algo/bilinear/bootstrap.hpp"

#include <random>

namespace fb {

std::vector<std::vector<float>> draw_identities(const FaceModel& model, int count,
                                                std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<float> normal(0.0f, 1.0f);
  std::vector<std::vector<float>> out(static_cast<std::size_t>(std::max(0, count)));
  for (auto& c : out) {
    c.resize(static_cast<std::size_t>(model.identity_count));
    for (auto& x : c) x = normal(rng);
  }
  return out;
}

FactoredTensor bootstrap_tensor(const FaceModel& model,
                                const std::vector<std::vector<float>>& identities) {
  const int rows = 3 * model.vertex_count;
  const int n_id_modes = model.identity_count;
  const int n_shapes = model.fitting_expression_count;
  const int k = 1 + n_id_modes + n_shapes;
  FactoredTensor t;
  t.rows = rows;
  t.identities = static_cast<int>(identities.size());
  t.expressions = 1 + n_shapes;
  t.basis.resize(rows, k);
  t.basis.col(0) = Eigen::Map<const Eigen::VectorXf>(model.neutral.data(), rows);
  for (int m = 0; m < n_id_modes; ++m)
    t.basis.col(1 + m) = Eigen::Map<const Eigen::VectorXf>(model.identity_mode(m).data(), rows);
  for (int j = 0; j < n_shapes; ++j)
    t.basis.col(1 + n_id_modes + j) =
        Eigen::Map<const Eigen::VectorXf>(model.expression_shape(j).data(), rows);
  t.coefficients =
      Eigen::MatrixXd::Zero(k, static_cast<Eigen::Index>(t.identities) * t.expressions);
  for (int e = 0; e < t.expressions; ++e)
    for (int i = 0; i < t.identities; ++i) {
      auto col = t.coefficients.col(static_cast<Eigen::Index>(e) * t.identities + i);
      col[0] = 1.0;
      const auto& c = identities[static_cast<std::size_t>(i)];
      for (int m = 0; m < n_id_modes && m < static_cast<int>(c.size()); ++m)
        col[1 + m] = c[static_cast<std::size_t>(m)];
      if (e > 0) col[n_id_modes + e] = 1.0;  // expression e is fitting shape e - 1
    }
  return t;
}

std::vector<std::string> bootstrap_expression_names(const FaceModel& model) {
  std::vector<std::string> names{"neutral"};
  for (int j = 0; j < model.fitting_expression_count; ++j)
    names.push_back(model.expression_names[static_cast<std::size_t>(j)]);
  return names;
}

BilinearModel make_bilinear_model(const TruncatedTensor& t, const FaceModel& topology,
                                  std::vector<std::string> expression_names, std::string metadata) {
  BilinearModel m;
  m.vertex_count = t.rows / 3;
  m.face_vertex_count = std::min(topology.face_vertex_count, m.vertex_count);
  m.id_knobs = t.id_knobs;
  m.exp_knobs = t.exp_knobs;
  m.identity_count = static_cast<int>(t.identity.rows());
  m.expression_count = static_cast<int>(t.expression.rows());
  m.core = t.core;
  m.identity_factors.resize(static_cast<std::size_t>(m.identity_count) * m.id_knobs);
  for (int i = 0; i < m.identity_count; ++i)
    for (int a = 0; a < m.id_knobs; ++a)
      m.identity_factors[static_cast<std::size_t>(i) * m.id_knobs + a] =
          static_cast<float>(t.identity(i, a));
  m.expression_factors.resize(static_cast<std::size_t>(m.expression_count) * m.exp_knobs);
  for (int e = 0; e < m.expression_count; ++e)
    for (int b = 0; b < m.exp_knobs; ++b)
      m.expression_factors[static_cast<std::size_t>(e) * m.exp_knobs + b] =
          static_cast<float>(t.expression(e, b));
  for (Eigen::Index i = 0; i < t.identity_spectrum.size(); ++i)
    m.identity_spectrum.push_back(static_cast<float>(t.identity_spectrum[i]));
  for (Eigen::Index i = 0; i < t.expression_spectrum.size(); ++i)
    m.expression_spectrum.push_back(static_cast<float>(t.expression_spectrum[i]));
  m.expression_names = std::move(expression_names);
  m.triangles = topology.triangles;
  m.landmark_vertices = topology.landmark_vertices;
  m.metadata = std::move(metadata);
  return m;
}

}  // namespace fb
