#include "algo/tracking/bilinear_subject.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include <Eigen/Eigenvalues>

namespace fb {
namespace {

// C x_3 u: 3V x Kid, column a = sum_b u_b C[:, a, b] (a neutral or an expression per identity
// knob).
Eigen::MatrixXf contract_expression(const BilinearModel& m, std::span<const float> u) {
  const std::size_t n = static_cast<std::size_t>(m.coordinate_count());
  Eigen::MatrixXf out = Eigen::MatrixXf::Zero(static_cast<Eigen::Index>(n), m.id_knobs);
  for (int b = 0; b < m.exp_knobs; ++b) {
    const float ub = u[static_cast<std::size_t>(b)];
    if (ub == 0.0f) continue;
    for (int a = 0; a < m.id_knobs; ++a) {
      const float* block = m.core.data() + (static_cast<std::size_t>(b) * m.id_knobs + a) * n;
      out.col(a) += ub * Eigen::Map<const Eigen::VectorXf>(block, static_cast<Eigen::Index>(n));
    }
  }
  return out;
}

// C x_2 w at `coords` coordinates, coordinate_of(x) being the x-th one's index into 3V:
// coords x Kexp, E(x, b) = sum_a w_a C[coordinate_of(x), a, b].
template <typename CoordinateOf>
Eigen::MatrixXf contract_identity(const BilinearModel& m, std::span<const float> w,
                                  std::size_t coords, CoordinateOf coordinate_of) {
  const std::size_t n = static_cast<std::size_t>(m.coordinate_count());
  Eigen::MatrixXf out = Eigen::MatrixXf::Zero(static_cast<Eigen::Index>(coords), m.exp_knobs);
  for (int b = 0; b < m.exp_knobs; ++b) {
    float* column = out.col(b).data();
    for (int a = 0; a < m.id_knobs; ++a) {
      const float wa = w[static_cast<std::size_t>(a)];
      const float* block = m.core.data() + (static_cast<std::size_t>(b) * m.id_knobs + a) * n;
      for (std::size_t x = 0; x < coords; ++x) column[x] += wa * block[coordinate_of(x)];
    }
  }
  return out;
}

// u_e - u_0: expression e's knobs relative to the neutral's.
Eigen::VectorXf expression_offset(const BilinearModel& m, int e) {
  const auto ue = m.expression_row(e), u0 = m.expression_row(0);
  Eigen::VectorXf du(m.exp_knobs);
  for (int b = 0; b < m.exp_knobs; ++b)
    du[b] = ue[static_cast<std::size_t>(b)] - u0[static_cast<std::size_t>(b)];
  return du;
}

}  // namespace

Result<BilinearTrackingModel> make_bilinear_tracking_model(const BilinearModel& bilinear,
                                                           const FaceModel& topology) {
  if (bilinear.vertex_count != topology.vertex_count ||
      bilinear.face_vertex_count != topology.face_vertex_count) {
    return fail("the bilinear model has " + std::to_string(bilinear.vertex_count) +
                " vertices (face region " + std::to_string(bilinear.face_vertex_count) +
                "), the face model " + std::to_string(topology.vertex_count) + " (" +
                std::to_string(topology.face_vertex_count) +
                "); build it from this face model or from rigs in its topology");
  }
  if (bilinear.landmark_vertices != topology.landmark_vertices) {
    return fail(
        "the bilinear model's 68 landmark vertices are not the face model's; rebuild it "
        "with `facebooth model build`");
  }
  if (bilinear.expression_count < 2 || bilinear.expression_names.empty() ||
      bilinear.expression_names.front() != "neutral" || bilinear.identity_count < 2) {
    return fail(
        "the bilinear model needs a neutral (expression 0) and at least 2 training "
        "identities; rebuild it with `facebooth model build`");
  }
  const int kid = bilinear.id_knobs, rows = bilinear.identity_count;
  const std::size_t n3 = static_cast<std::size_t>(bilinear.coordinate_count());
  BilinearTrackingModel out;

  // The training identities' mean and principal directions in knob space.
  Eigen::MatrixXf w(rows, kid);
  for (int i = 0; i < rows; ++i) {
    const auto r = bilinear.identity_row(i);
    for (int a = 0; a < kid; ++a) w(i, a) = r[static_cast<std::size_t>(a)];
  }
  const Eigen::VectorXf mean = w.colwise().mean().transpose();
  const Eigen::MatrixXf centred = w.rowwise() - mean.transpose();
  const Eigen::MatrixXf covariance = centred.transpose() * centred / static_cast<float>(rows);
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXf> eig(covariance);
  if (eig.info() != Eigen::Success)
    return fail("the bilinear model's identity factors are invalid");
  // Descending; directions with no spread in the training set are no identity mode.
  const float largest = eig.eigenvalues().maxCoeff();
  std::vector<int> kept;
  for (int a = kid - 1; a >= 0; --a) {
    if (eig.eigenvalues()[a] > 1e-6f * largest) kept.push_back(a);
  }
  out.mean_identity.assign(mean.data(), mean.data() + kid);
  out.knobs_per_mode.resize(kid, static_cast<Eigen::Index>(kept.size()));
  for (std::size_t m = 0; m < kept.size(); ++m) {
    out.knobs_per_mode.col(static_cast<Eigen::Index>(m)) =
        eig.eigenvectors().col(kept[m]) * std::sqrt(eig.eigenvalues()[kept[m]]);
  }

  // neutral(w) = M w with M = C x_3 u_0 (3V x Kid).
  const Eigen::MatrixXf neutral_per_knob =
      contract_expression(bilinear, bilinear.expression_row(0));
  // The topology, names and vertex subsets are the face model's; neutral and bases are replaced.
  FaceModel& face = out.face;
  face = topology;
  face.identity_count = static_cast<int>(kept.size());
  face.provenance = "bilinear model (" + std::to_string(kid) + " x " +
                    std::to_string(bilinear.exp_knobs) + " knobs) over the face model's topology";
  const Eigen::VectorXf neutral = neutral_per_knob * mean;
  face.neutral.assign(neutral.data(), neutral.data() + n3);
  const Eigen::MatrixXf modes = neutral_per_knob * out.knobs_per_mode;
  face.identity_basis.assign(modes.data(), modes.data() + modes.size());

  // Expression deltas of the mean identity, (C x_2 w_mean)(u_e - u_0); shapes the bilinear
  // model does not name keep the topology's.
  out.expression_row.assign(static_cast<std::size_t>(face.fitting_expression_count), -1);
  const Eigen::MatrixXf per_exp_knob =
      contract_identity(bilinear, out.mean_identity, n3, [](std::size_t x) { return x; });
  for (int j = 0; j < face.expression_count; ++j) {
    const auto& name = face.expression_names[static_cast<std::size_t>(j)];
    const auto it =
        std::find(bilinear.expression_names.begin() + 1, bilinear.expression_names.end(), name);
    if (it == bilinear.expression_names.end()) continue;
    const int e = static_cast<int>(it - bilinear.expression_names.begin());
    if (j < face.fitting_expression_count) out.expression_row[static_cast<std::size_t>(j)] = e;
    const Eigen::VectorXf delta = per_exp_knob * expression_offset(bilinear, e);
    std::copy(delta.data(), delta.data() + n3,
              face.expression_basis.begin() + static_cast<std::ptrdiff_t>(j * n3));
  }
  if (std::none_of(out.expression_row.begin(), out.expression_row.end(),
                   [](int row) { return row >= 0; })) {
    return fail("none of the bilinear model's " + std::to_string(bilinear.expression_count - 1) +
                " expressions is named like one of the face model's fitting shapes (e.g. '" +
                topology.expression_names.front() +
                "'); build it from rigs in the face model's shape names");
  }
  return out;
}

std::vector<float> BilinearBlendshapes::knobs(std::span<const float> identity) const {
  const auto& k = tracking_.knobs_per_mode;
  Eigen::VectorXf c = Eigen::VectorXf::Zero(k.cols());
  for (Eigen::Index m = 0; m < c.size() && m < static_cast<Eigen::Index>(identity.size()); ++m)
    c[m] = identity[static_cast<std::size_t>(m)];
  const Eigen::VectorXf w =
      Eigen::Map<const Eigen::VectorXf>(tracking_.mean_identity.data(),
                                        static_cast<Eigen::Index>(tracking_.mean_identity.size())) +
      k * c;
  return {w.data(), w.data() + w.size()};
}

void BilinearBlendshapes::subject_deltas(std::span<const float> identity,
                                         std::span<const std::uint32_t> vertices,
                                         std::span<float> deltas) const {
  // delta_j = (C x_2 w)(u_e(j) - u_0) at the listed vertices only.
  const std::size_t coords = 3 * vertices.size();
  const Eigen::MatrixXf e =
      contract_identity(bilinear_, knobs(identity), coords,
                        [&](std::size_t x) { return 3 * vertices[x / 3] + x % 3; });
  for (std::size_t j = 0; j < tracking_.expression_row.size(); ++j) {
    const int row = tracking_.expression_row[j];
    if (row < 0 || (j + 1) * coords > deltas.size()) continue;
    Eigen::Map<Eigen::VectorXf>(deltas.data() + j * coords, static_cast<Eigen::Index>(coords)) =
        e * expression_offset(bilinear_, row);
  }
}

}  // namespace fb
