#include "algo/rigging/example_rigging.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>
#include <thread>

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/LU>
#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>

namespace fb {
namespace {

using Mat3 = Eigen::Matrix3d;
using Vec3 = Eigen::Vector3d;
using Edges = Eigen::Matrix<double, 6, 1>;  // the two edge columns, stacked (e1 xyz, e2 xyz)

Vec3 vertex(std::span<const float> xyz, std::uint32_t i) {
  return {xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]};
}

// F = [v2 - v1, v3 - v1, n / sqrt|n|] (Sumner and Popovic's fourth-vertex normal).
Mat3 frame(std::span<const float> xyz, const std::uint32_t* tri) {
  const Vec3 a = vertex(xyz, tri[0]);
  const Vec3 e1 = vertex(xyz, tri[1]) - a;
  const Vec3 e2 = vertex(xyz, tri[2]) - a;
  Vec3 n = e1.cross(e2);
  const double len = n.norm();
  if (len > 0) n /= std::sqrt(len);
  Mat3 f;
  f << e1, e2, n;
  return f;
}

Edges edges_of(std::span<const float> xyz, const std::uint32_t* tri) {
  const Vec3 a = vertex(xyz, tri[0]);
  Edges e;
  e << vertex(xyz, tri[1]) - a, vertex(xyz, tri[2]) - a;
  return e;
}

template <class Fn>
void parallel_for(int count, int threads, Fn fn) {
  threads = std::clamp(threads, 1, 16);
  if (threads == 1 || count < 256) {
    fn(0, count);
    return;
  }
  std::vector<std::thread> pool;
  const int chunk = (count + threads - 1) / threads;
  for (int k = 0; k < threads; ++k) {
    const int begin = k * chunk, end = std::min(count, begin + chunk);
    if (begin < end) pool.emplace_back([=] { fn(begin, end); });
  }
  for (auto& t : pool) t.join();
}

// Bounded least squares min 0.5 a^T H a - g^T a, a in [0, 1]^n, by projected coordinate
// descent (H is SPD and small, so this converges quickly and needs no active-set bookkeeping).
void box_qp(const Eigen::MatrixXd& h, const Eigen::VectorXd& g, Eigen::VectorXd& a) {
  Eigen::VectorXd grad = h * a - g;
  for (int sweep = 0; sweep < 200; ++sweep) {
    double change = 0;
    for (int j = 0; j < a.size(); ++j) {
      if (h(j, j) <= 0) continue;
      const double next = std::clamp(a[j] - grad[j] / h(j, j), 0.0, 1.0);
      const double d = next - a[j];
      if (d != 0) {
        grad += h.col(j) * d;
        a[j] = next;
        change = std::max(change, std::abs(d));
      }
    }
    if (change < 1e-7) break;
  }
}

}  // namespace

std::vector<float> evaluate_rig(std::span<const float> neutral,
                                const std::vector<std::vector<float>>& shapes,
                                std::span<const float> weights) {
  std::vector<float> out(neutral.begin(), neutral.end());
  for (std::size_t j = 0; j < shapes.size() && j < weights.size(); ++j) {
    const float w = weights[j];
    if (w == 0.0f) continue;
    const auto& s = shapes[j];
    for (std::size_t k = 0; k < out.size(); ++k) out[k] += w * (s[k] - neutral[k]);
  }
  return out;
}

namespace {

// The rig's sizes, checked against the examples and their weights.
struct RigSizes {
  std::size_t floats = 0;
  int vertex_count = 0, shape_count = 0, triangle_count = 0, example_count = 0;
};

Result<RigSizes> check_input(const RigInput& input) {
  const std::size_t floats = input.generic_neutral.size();
  const int vertex_count = static_cast<int>(floats / 3);
  const int shape_count = static_cast<int>(input.generic_shapes.size());
  const int triangle_count = static_cast<int>(input.triangles.size() / 3);
  if (vertex_count == 0 || floats % 3 != 0 || triangle_count == 0)
    return fail("rigging: the generic rig is empty (no vertices or no triangles)");
  if (shape_count == 0) return fail("rigging: the generic rig has no blendshapes");
  for (int j = 0; j < shape_count; ++j)
    if (input.generic_shapes[static_cast<std::size_t>(j)].size() != floats)
      return fail("rigging: generic shape " + std::to_string(j + 1) + " has " +
                  std::to_string(input.generic_shapes[static_cast<std::size_t>(j)].size() / 3) +
                  " vertices, the generic neutral " + std::to_string(vertex_count));
  for (auto v : input.triangles)
    if (v >= static_cast<std::uint32_t>(vertex_count))
      return fail("rigging: a triangle references vertex " + std::to_string(v) + " of " +
                  std::to_string(vertex_count));
  const int example_count = static_cast<int>(input.examples.size()) - 1;  // m, without S_0
  if (example_count < 1)
    return fail("rigging: need the neutral and at least one expression example, got " +
                std::to_string(input.examples.size()) + " meshes");
  if (input.example_weights.size() != input.examples.size())
    return fail("rigging: " + std::to_string(input.examples.size()) + " examples but " +
                std::to_string(input.example_weights.size()) + " weight rows");
  for (int i = 0; i <= example_count; ++i) {
    if (input.examples[static_cast<std::size_t>(i)].size() != floats)
      return fail("rigging: example " + std::to_string(i) + " has " +
                  std::to_string(input.examples[static_cast<std::size_t>(i)].size() / 3) +
                  " vertices, the generic rig " + std::to_string(vertex_count) +
                  " (examples must be fitted meshes in the model topology)");
    const auto& w = input.example_weights[static_cast<std::size_t>(i)];
    if (i > 0 && static_cast<int>(w.size()) != shape_count)
      return fail("rigging: example " + std::to_string(i) + " has " + std::to_string(w.size()) +
                  " weights, the generic rig " + std::to_string(shape_count) + " shapes");
    for (float x : w)
      if (!(x >= 0.0f && x <= 1.0f))
        return fail("rigging: example " + std::to_string(i) + " has a weight outside [0, 1]");
  }
  return RigSizes{floats, vertex_count, shape_count, triangle_count, example_count};
}

// Per-triangle constants: example edge deltas R (m x 6), prior targets D* (n x 6) and weights.
struct TriangleConstants {
  std::vector<double> example_delta, prior_target, prior_w;
};

TriangleConstants triangle_constants(const RigInput& input, const RigOptions& options,
                                     const RigSizes& z) {
  const int n = z.shape_count, m = z.example_count, triangle_count = z.triangle_count;
  const std::span<const float> s0 = input.examples[0];
  const std::uint32_t* tris = input.triangles.data();
  TriangleConstants c;
  std::vector<double>& example_delta = c.example_delta;
  std::vector<double>& prior_target = c.prior_target;
  std::vector<double>& prior_w = c.prior_w;
  example_delta.resize(static_cast<std::size_t>(triangle_count) * m * 6);
  prior_target.resize(static_cast<std::size_t>(triangle_count) * n * 6);
  prior_w.resize(static_cast<std::size_t>(triangle_count) * n);
  parallel_for(triangle_count, options.threads, [&](int begin, int end) {
    for (int t = begin; t < end; ++t) {
      const std::uint32_t* tri = tris + 3 * t;
      const Edges e0 = edges_of(s0, tri);
      for (int i = 0; i < m; ++i) {
        const Edges d = edges_of(input.examples[static_cast<std::size_t>(i + 1)], tri) - e0;
        std::copy(d.data(), d.data() + 6,
                  &example_delta[(static_cast<std::size_t>(t) * m + i) * 6]);
      }
      const Mat3 g0 = frame(input.generic_neutral, tri);
      const double det = g0.determinant();
      const bool invertible = std::isfinite(det) && std::abs(det) > 1e-12;
      const Mat3 g0_inv = invertible ? Mat3(g0.inverse()) : Mat3::Identity();
      Eigen::Matrix<double, 3, 2> e0m;
      e0m << e0.head<3>(), e0.tail<3>();
      for (int j = 0; j < n; ++j) {
        Mat3 q = Mat3::Zero();
        if (invertible) q = frame(input.generic_shapes[static_cast<std::size_t>(j)], tri) * g0_inv;
        if (invertible) q -= Mat3::Identity();
        const double norm = q.norm();
        prior_w[static_cast<std::size_t>(t) * n + j] =
            std::pow((1.0 + norm) / (options.kappa + norm), options.theta);
        const Eigen::Matrix<double, 3, 2> target = q * e0m;
        double* out = &prior_target[(static_cast<std::size_t>(t) * n + j) * 6];
        for (int k = 0; k < 3; ++k) {
          out[k] = target(k, 0);
          out[3 + k] = target(k, 1);
        }
      }
    }
  });
  return c;
}

// Vertex solve: K^T K + eps I, K = the three directed edges of every triangle.
Result<void> factorise_vertices(const RigInput& input, const RigOptions& options, const RigSizes& z,
                                Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>>& poisson) {
  const int triangle_count = z.triangle_count, vertex_count = z.vertex_count;
  const std::uint32_t* tris = input.triangles.data();
  std::vector<Eigen::Triplet<double>> entries;
  entries.reserve(static_cast<std::size_t>(triangle_count) * 12 + vertex_count);
  for (int t = 0; t < triangle_count; ++t) {
    const std::uint32_t* tri = tris + 3 * t;
    const int pairs[3][2] = {{0, 1}, {0, 2}, {1, 2}};
    for (const auto& p : pairs) {
      const int a = static_cast<int>(tri[p[0]]), b = static_cast<int>(tri[p[1]]);
      entries.emplace_back(a, a, 1.0);
      entries.emplace_back(b, b, 1.0);
      entries.emplace_back(a, b, -1.0);
      entries.emplace_back(b, a, -1.0);
    }
  }
  for (int v = 0; v < vertex_count; ++v) entries.emplace_back(v, v, options.anchor_weight);
  Eigen::SparseMatrix<double> l(vertex_count, vertex_count);
  l.setFromTriplets(entries.begin(), entries.end());
  poisson.compute(l);
  if (poisson.info() != Eigen::Success)
    return fail("rigging: the vertex system could not be factorised (is the mesh degenerate?)");
  return success();
}

// The vertices the example weights are re-estimated on.
std::vector<std::uint32_t> weight_vertices_of(const RigOptions& options, int vertex_count) {
  std::vector<std::uint32_t> weight_vertices;
  const int stride = std::max(1, options.weight_vertex_stride);
  if (options.weight_vertices.empty()) {
    for (int v = 0; v < vertex_count; v += stride) weight_vertices.push_back(v);
  } else {
    for (std::size_t k = 0; k < options.weight_vertices.size(); k += stride)
      if (options.weight_vertices[k] < static_cast<std::uint32_t>(vertex_count))
        weight_vertices.push_back(options.weight_vertices[k]);
  }
  return weight_vertices;
}

// 1. Per-triangle edge deltas of every shape for the current example weights.
void solve_edges(const RigOptions& options, const RigSizes& z, const TriangleConstants& c,
                 const RigResult& result, std::vector<double>& edge_solution) {
  const int n = z.shape_count, m = z.example_count, triangle_count = z.triangle_count;
  const std::vector<double>& example_delta = c.example_delta;
  const std::vector<double>& prior_target = c.prior_target;
  const std::vector<double>& prior_w = c.prior_w;
  Eigen::MatrixXd a(m, n);
  for (int i = 0; i < m; ++i)
    for (int j = 0; j < n; ++j) a(i, j) = result.weights[static_cast<std::size_t>(i + 1)][j];
  const Eigen::MatrixXd ata = a.transpose() * a;
  parallel_for(triangle_count, options.threads, [&](int begin, int end) {
    Eigen::MatrixXd h(n, n);
    Eigen::MatrixXd rhs(n, 6);
    Eigen::LLT<Eigen::MatrixXd> llt(n);
    for (int t = begin; t < end; ++t) {
      const Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 6, Eigen::RowMajor>> r(
          &example_delta[static_cast<std::size_t>(t) * m * 6], m, 6);
      const Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 6, Eigen::RowMajor>> d(
          &prior_target[static_cast<std::size_t>(t) * n * 6], n, 6);
      h = ata;
      rhs.noalias() = a.transpose() * r;
      for (int j = 0; j < n; ++j) {
        const double w = options.prior_weight * prior_w[static_cast<std::size_t>(t) * n + j];
        h(j, j) += w;
        rhs.row(j) += w * d.row(j);
      }
      llt.compute(h);
      Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, 6, Eigen::RowMajor>> x(
          &edge_solution[static_cast<std::size_t>(t) * n * 6], n, 6);
      x = llt.solve(rhs);
    }
  });
}

// 2. Vertices of every shape from its edge deltas: one multi-column back-substitution.
void solve_vertices(const RigInput& input, const RigOptions& options, const RigSizes& z,
                    const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>>& poisson,
                    const std::vector<double>& edge_solution, RigResult& result) {
  const int n = z.shape_count, triangle_count = z.triangle_count, vertex_count = z.vertex_count;
  const std::span<const float> s0 = input.examples[0];
  const std::uint32_t* tris = input.triangles.data();
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(vertex_count, 3 * n);
  for (int j = 0; j < n; ++j) {
    const auto& aj = input.generic_shapes[static_cast<std::size_t>(j)];
    for (int v = 0; v < vertex_count; ++v)
      for (int k = 0; k < 3; ++k)
        rhs(v, 3 * j + k) = options.anchor_weight *
                            (static_cast<double>(aj[3 * v + k]) - input.generic_neutral[3 * v + k]);
  }
  for (int t = 0; t < triangle_count; ++t) {
    const std::uint32_t* tri = tris + 3 * t;
    for (int j = 0; j < n; ++j) {
      const double* x = &edge_solution[(static_cast<std::size_t>(t) * n + j) * 6];
      for (int k = 0; k < 3; ++k) {
        const double e1 = x[k], e2 = x[3 + k], e3 = x[3 + k] - x[k];
        // Edge (a -> b) with target y adds y to row b and -y to row a.
        rhs(tri[1], 3 * j + k) += e1;
        rhs(tri[0], 3 * j + k) -= e1;
        rhs(tri[2], 3 * j + k) += e2;
        rhs(tri[0], 3 * j + k) -= e2;
        rhs(tri[2], 3 * j + k) += e3;
        rhs(tri[1], 3 * j + k) -= e3;
      }
    }
  }
  const Eigen::MatrixXd delta = poisson.solve(rhs);
  for (int j = 0; j < n; ++j) {
    auto& shape = result.shapes[static_cast<std::size_t>(j)];
    for (int v = 0; v < vertex_count; ++v)
      for (int k = 0; k < 3; ++k)
        shape[3 * v + k] = static_cast<float>(s0[3 * v + k] + delta(v, 3 * j + k));
  }
}

// 3. The example weights re-estimated for the current shapes (box-constrained to [0, 1],
// pulled towards the given recipes).
void update_example_weights(const RigInput& input, const RigOptions& options, const RigSizes& z,
                            const std::vector<std::uint32_t>& weight_vertices, RigResult& result) {
  const int n = z.shape_count, m = z.example_count;
  const std::span<const float> s0 = input.examples[0];
  const int ns = static_cast<int>(weight_vertices.size());
  Eigen::MatrixXd basis(3 * ns, n);
  for (int j = 0; j < n; ++j)
    for (int s = 0; s < ns; ++s)
      for (int k = 0; k < 3; ++k) {
        const std::uint32_t v = weight_vertices[static_cast<std::size_t>(s)];
        basis(3 * s + k, j) = result.shapes[static_cast<std::size_t>(j)][3 * v + k] -
                              static_cast<double>(s0[3 * v + k]);
      }
  const double gamma = options.weight_regularization;
  Eigen::MatrixXd h = basis.transpose() * basis / ns;
  h.diagonal().array() += gamma;
  for (int i = 1; i <= m; ++i) {
    Eigen::VectorXd target(3 * ns);
    for (int s = 0; s < ns; ++s)
      for (int k = 0; k < 3; ++k) {
        const std::uint32_t v = weight_vertices[static_cast<std::size_t>(s)];
        target[3 * s + k] = input.examples[static_cast<std::size_t>(i)][3 * v + k] -
                            static_cast<double>(s0[3 * v + k]);
      }
    Eigen::VectorXd guide(n);
    for (int j = 0; j < n; ++j) guide[j] = input.example_weights[static_cast<std::size_t>(i)][j];
    const Eigen::VectorXd g = basis.transpose() * target / ns + gamma * guide;
    Eigen::VectorXd alpha(n);
    for (int j = 0; j < n; ++j) alpha[j] = result.weights[static_cast<std::size_t>(i)][j];
    box_qp(h, g, alpha);
    for (int j = 0; j < n; ++j)
      result.weights[static_cast<std::size_t>(i)][j] = static_cast<float>(alpha[j]);
  }
}

// Residuals of this round: every example against the rig at its weights.
void add_residuals(const RigInput& input, const RigSizes& z, RigResult& result) {
  const int m = z.example_count, vertex_count = z.vertex_count;
  double sum = 0;
  result.vertex_residual_mm.assign(static_cast<std::size_t>(m + 1), {});
  result.example_residual_mm.assign(static_cast<std::size_t>(m + 1), 0.0);
  for (int i = 0; i <= m; ++i) {
    const auto mesh =
        evaluate_rig(result.neutral, result.shapes, result.weights[static_cast<std::size_t>(i)]);
    const auto& ex = input.examples[static_cast<std::size_t>(i)];
    auto& res = result.vertex_residual_mm[static_cast<std::size_t>(i)];
    res.resize(static_cast<std::size_t>(vertex_count));
    double s = 0;
    for (int v = 0; v < vertex_count; ++v) {
      const double d = (vertex(mesh, v) - vertex(ex, v)).norm();
      res[static_cast<std::size_t>(v)] = static_cast<float>(d);
      s += d;
    }
    result.example_residual_mm[static_cast<std::size_t>(i)] = s / vertex_count;
    if (i > 0) sum += s / vertex_count;
  }
  result.round_residual_mm.push_back(sum / m);
}

}  // namespace

Result<RigResult> rig_subject(const RigInput& input, const RigOptions& options) {
  const auto t_start = std::chrono::steady_clock::now();
  auto sizes = check_input(input);
  if (!sizes) return sizes.failure();
  const RigSizes& z = *sizes;
  auto report = [&](std::string_view stage, double f) {
    if (options.progress) options.progress(stage, std::clamp(f, 0.0, 1.0));
  };

  const int n = z.shape_count;
  const std::span<const float> s0 = input.examples[0];
  const TriangleConstants constants = triangle_constants(input, options, z);
  report("prepare", 0.05);

  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> poisson;
  if (auto ok = factorise_vertices(input, options, z, poisson); !ok) return ok.failure();
  report("factorise", 0.1);

  RigResult result;
  result.neutral.assign(s0.begin(), s0.end());
  result.shapes.assign(static_cast<std::size_t>(n), std::vector<float>(z.floats));
  result.weights = input.example_weights;
  result.weights[0].assign(static_cast<std::size_t>(n), 0.0f);
  const std::vector<std::uint32_t> weight_vertices = weight_vertices_of(options, z.vertex_count);

  std::vector<double> edge_solution(static_cast<std::size_t>(z.triangle_count) * n * 6);
  const int rounds = std::max(1, options.rounds);
  for (int round = 0; round < rounds; ++round) {
    const double base = 0.1 + 0.9 * round / rounds, span = 0.9 / rounds;
    solve_edges(options, z, constants, result, edge_solution);
    report("blendshapes", base + 0.6 * span);
    solve_vertices(input, options, z, poisson, edge_solution, result);
    report("vertices", base + 0.8 * span);
    // Not after the last round: the shapes were solved for these weights.
    if (options.update_weights && round + 1 < rounds)
      update_example_weights(input, options, z, weight_vertices, result);
    add_residuals(input, z, result);
    report("weights", base + span);
  }
  result.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  return result;
}

}  // namespace fb
