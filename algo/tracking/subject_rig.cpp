#include "algo/tracking/subject_rig.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <string_view>
#include <unordered_map>

#include <Eigen/Cholesky>

namespace fb {
namespace {

Eigen::Vector3f vertex_of(std::span<const float> mesh, std::uint32_t v) {
  return Eigen::Vector3f(mesh[3 * v], mesh[3 * v + 1], mesh[3 * v + 2]);
}

// Boundary vertices (edges of one triangle): the eye and mouth openings.
std::vector<char> boundary_vertices(const FaceModel& model) {
  std::vector<char> boundary(static_cast<std::size_t>(model.vertex_count), 0);
  std::unordered_map<long long, int> edges;
  auto key = [](std::uint32_t a, std::uint32_t b) {
    return static_cast<long long>(std::min(a, b)) * 1000003LL + std::max(a, b);
  };
  for (std::size_t t = 0; t + 2 < model.triangles.size(); t += 3) {
    for (int e = 0; e < 3; ++e)
      ++edges[key(model.triangles[t + e], model.triangles[t + (e + 1) % 3])];
  }
  for (const auto& [k, count] : edges) {
    if (count == 1) {
      boundary[static_cast<std::size_t>(k / 1000003LL)] = 1;
      boundary[static_cast<std::size_t>(k % 1000003LL)] = 1;
    }
  }
  return boundary;
}

// Front-facing fitting vertices of the face, away from the openings: depth there sees eyeballs,
// teeth or the mouth cavity, which the skin model does not have.
std::vector<std::uint32_t> candidate_vertices(const FaceModel& model,
                                              const RigSampleOptions& options) {
  std::span<const float> neutral = model.neutral;
  std::vector<Eigen::Vector3f> vn(static_cast<std::size_t>(model.vertex_count),
                                  Eigen::Vector3f::Zero());
  auto nv = [&](std::uint32_t v) { return vertex_of(neutral, v); };
  for (std::size_t t = 0; t + 2 < model.triangles.size(); t += 3) {
    const auto a = model.triangles[t], b = model.triangles[t + 1], c = model.triangles[t + 2];
    const Eigen::Vector3f nn = (nv(b) - nv(a)).cross(nv(c) - nv(a));
    vn[a] += nn, vn[b] += nn, vn[c] += nn;
  }
  const std::vector<char> boundary = boundary_vertices(model);
  std::vector<Eigen::Vector3f> hole_points;
  for (int v = 0; v < model.face_vertex_count; ++v) {
    if (boundary[static_cast<std::size_t>(v)])
      hole_points.push_back(nv(static_cast<std::uint32_t>(v)));
  }
  std::vector<std::uint32_t> candidates;
  for (auto v : model.fitting_vertices) {
    if (static_cast<int>(v) >= model.face_vertex_count) continue;
    if (vn[v].normalized().z() < 0.25f) continue;
    bool near_hole = false;
    for (const auto& h : hole_points) {
      if ((h - nv(v)).squaredNorm() < options.hole_margin_mm * options.hole_margin_mm) {
        near_hole = true;
        break;
      }
    }
    if (!near_hole) candidates.push_back(v);
  }
  return candidates;
}

// One candidate per grid cell, plus the most-displaced vertices of every shape so small shapes
// (blinks, brows) are seen.
std::vector<std::uint32_t> select_samples(const FaceModel& model, int k,
                                          const RigSampleOptions& options,
                                          const std::vector<std::uint32_t>& candidates) {
  std::unordered_map<long long, std::uint32_t> cells;
  std::vector<char> chosen(static_cast<std::size_t>(model.vertex_count), 0);
  const float spacing = std::max(1.0f, options.sample_spacing_mm);
  for (auto v : candidates) {
    const Eigen::Vector3f p = vertex_of(model.neutral, v);
    const long long key = (static_cast<long long>(std::floor(p.x() / spacing)) + 100000) * 200001 +
                          static_cast<long long>(std::floor(p.y() / spacing)) + 100000;
    if (cells.emplace(key, v).second) chosen[v] = 1;
  }
  for (int j = 0; j < k; ++j) {
    const auto shape = model.expression_shape(j);
    std::vector<std::pair<float, std::uint32_t>> moved;
    for (auto v : candidates) {
      const float d = Eigen::Vector3f(shape[3 * v], shape[3 * v + 1], shape[3 * v + 2]).norm();
      if (d > 0.5f) moved.emplace_back(d, v);
    }
    const std::size_t take = std::min<std::size_t>(
        moved.size(), static_cast<std::size_t>(options.extra_samples_per_shape));
    std::partial_sort(moved.begin(), moved.begin() + take, moved.end(),
                      [](const auto& a, const auto& b) { return a.first > b.first; });
    for (std::size_t i = 0; i < take; ++i) chosen[moved[i].second] = 1;
  }
  std::vector<std::uint32_t> samples;
  for (int v = 0; v < model.vertex_count; ++v) {
    if (chosen[static_cast<std::size_t>(v)]) samples.push_back(static_cast<std::uint32_t>(v));
  }
  return samples;
}

// Per shape: is it a gaze shape; the antagonist pairs (WeightSolverOptions::antagonist_weight).
void classify_shapes(const FaceModel& model, SubjectRig& rig) {
  rig.gaze_shape.resize(static_cast<std::size_t>(rig.k));
  for (int j = 0; j < rig.k; ++j)
    rig.gaze_shape[static_cast<std::size_t>(j)] =
        static_cast<std::size_t>(j) < model.expression_names.size() &&
                is_gaze_shape(model.expression_names[static_cast<std::size_t>(j)])
            ? 1
            : 0;
  for (const char* side : {"_L", "_R"}) {
    constexpr std::pair<std::string_view, std::string_view> kPairs[] = {{"browDown", "browInnerUp"},
                                                                        {"browDown", "browOuterUp"},
                                                                        {"eyeWide", "eyeBlink"},
                                                                        {"eyeWide", "eyeSquint"}};
    for (const auto& [first, second] : kPairs) {
      const int a = model.expression_index(std::string(first) + side);
      const int b = model.expression_index(std::string(second) + side);
      if (a >= 0 && b >= 0 && a < rig.k && b < rig.k) rig.antagonists.emplace_back(a, b);
    }
  }
}

// The identity-independent bases at the samples and landmarks, and the rigid part of every
// identity mode at the samples (least squares against the 6 rigid motions of the mean face
// about its sample centroid), removed from the basis.
void fill_bases(const FaceModel& model, SubjectRig& rig) {
  const int n = rig.n;
  rig.expression_at_samples.resize(3 * n, rig.k);
  rig.identity_at_samples.resize(3 * n, rig.modes);
  rig.expression_at_landmarks.resize(3 * 68, rig.k);
  rig.identity_at_landmarks.resize(3 * 68, rig.modes);
  auto fill = [&](auto& out, std::span<const std::uint32_t> vertices, bool expression) {
    const int columns = expression ? rig.k : rig.modes;
    for (int j = 0; j < columns; ++j) {
      const auto shape = expression ? model.expression_shape(j) : model.identity_mode(j);
      for (std::size_t i = 0; i < vertices.size(); ++i) {
        for (int a = 0; a < 3; ++a)
          out(3 * static_cast<int>(i) + a, j) = shape[3 * vertices[i] + a];
      }
    }
  };
  fill(rig.expression_at_samples, rig.sample_vertices, true);
  fill(rig.identity_at_samples, rig.sample_vertices, false);
  fill(rig.expression_at_landmarks, model.landmark_vertices, true);
  fill(rig.identity_at_landmarks, model.landmark_vertices, false);
  rig.model_expression_at_samples = rig.expression_at_samples;
  rig.model_expression_at_landmarks = rig.expression_at_landmarks;

  Eigen::Vector3f pivot = Eigen::Vector3f::Zero();
  for (auto v : rig.sample_vertices) pivot += vertex_of(model.neutral, v);
  pivot /= static_cast<float>(n);
  rig.rigid_pivot = pivot;
  Eigen::MatrixXd g(3 * n, 6);
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d x =
        (vertex_of(model.neutral, rig.sample_vertices[static_cast<std::size_t>(i)]) - pivot)
            .cast<double>();
    for (int a = 0; a < 3; ++a) {
      const Eigen::Vector3d e = Eigen::Vector3d::Unit(a);
      g.block<3, 1>(3 * i, a) = e.cross(x);  // rotation about axis a
      g.block<3, 1>(3 * i, 3 + a) = e;       // translation along a
    }
  }
  const Eigen::MatrixXd alpha =
      (g.transpose() * g).ldlt().solve(g.transpose() * rig.identity_at_samples.cast<double>());
  rig.rigid_of_mode = alpha.cast<float>();
  rig.identity_at_samples -= (g * alpha).cast<float>();
}

}  // namespace

Result<SubjectRig> SubjectRig::create(const FaceModel& model, const RigSampleOptions& samples,
                                      const WeightSolverOptions& priors, int identity_modes) {
  SubjectRig rig;
  rig.model = &model;
  rig.k = model.fitting_expression_count;
  rig.modes = std::clamp(identity_modes, 0, model.identity_count);
  rig.ridge = priors.ridge;
  rig.weak_shape_fraction = priors.weak_shape_fraction;
  rig.weak_shape_ridge = priors.weak_shape_ridge;
  rig.hold_gaze_shapes = priors.hold_gaze_shapes;
  classify_shapes(model, rig);
  const std::vector<std::uint32_t> candidates = candidate_vertices(model, samples);
  if (candidates.size() < 200) return fail("tracking: the face model has too few face vertices");
  rig.sample_vertices = select_samples(model, rig.k, samples, candidates);
  rig.n = static_cast<int>(rig.sample_vertices.size());
  fill_bases(model, rig);
  rig.current.resize(3 * rig.n);
  rig.landmark_current.resize(3 * 68);
  rig.landmark_offset = Eigen::VectorXf::Zero(3 * 68);
  return rig;
}

void SubjectRig::build(std::span<const float> coefficients, const ShapeVector& weights,
                       const Twist& rigid_offset) {
  identity.assign(std::max<std::size_t>(static_cast<std::size_t>(modes), coefficients.size()),
                  0.0f);
  std::copy(coefficients.begin(), coefficients.end(), identity.begin());
  // Full-mesh neutral of this identity for the normals (area-weighted vertex normals).
  const FaceModel& m = *model;
  mesh_scratch.resize(static_cast<std::size_t>(3 * m.vertex_count));
  m.evaluate(identity, {}, mesh_scratch);
  if (!rigid_offset.isZero()) {
    // Minus the linearised rigid motion: v -= omega x (mean_v - pivot) + t.
    const Eigen::Vector3f omega = rigid_offset.head<3>(), t = rigid_offset.tail<3>();
    for (int v = 0; v < m.vertex_count; ++v) {
      const Eigen::Vector3f mean(m.neutral[3 * v], m.neutral[3 * v + 1], m.neutral[3 * v + 2]);
      const Eigen::Vector3f d = omega.cross(mean - rigid_pivot) + t;
      for (int a = 0; a < 3; ++a) mesh_scratch[3 * v + a] -= d[a];
    }
  }
  finish(weights);
}

void SubjectRig::build_subject_blendshapes(const ShapeVector& weights) {
  if (subject_blendshapes == nullptr) return;
  use_model_expressions();  // the source overwrites the shapes it knows
  auto build_deltas = [&](auto& matrix, std::span<const std::uint32_t> vertices) {
    ColMatrix deltas = matrix;  // the layout SubjectBlendshapes writes
    subject_blendshapes->subject_deltas(
        identity, vertices,
        std::span<float>(deltas.data(), static_cast<std::size_t>(deltas.size())));
    matrix = deltas;
  };
  build_deltas(expression_at_samples, sample_vertices);
  build_deltas(expression_at_landmarks, model->landmark_vertices);
  custom_rig = true;  // reset() and the next identity start from the model's deltas again
  finish(weights);
  update_current(weights);
}

void SubjectRig::finish(const ShapeVector& weights) {
  const FaceModel& m = *model;
  mesh_normals.assign(static_cast<std::size_t>(m.vertex_count), Eigen::Vector3f::Zero());
  auto vertex = [&](std::uint32_t v) { return vertex_of(mesh_scratch, v); };
  for (std::size_t t = 0; t + 2 < m.triangles.size(); t += 3) {
    const auto a = m.triangles[t], b = m.triangles[t + 1], cc = m.triangles[t + 2];
    const Eigen::Vector3f nn = (vertex(b) - vertex(a)).cross(vertex(cc) - vertex(a));
    mesh_normals[a] += nn;
    mesh_normals[b] += nn;
    mesh_normals[cc] += nn;
  }
  base.resize(3 * n);
  normals.resize(static_cast<std::size_t>(n));
  centroid.setZero();
  nose_z = -std::numeric_limits<float>::infinity();
  for (int i = 0; i < n; ++i) {
    const auto v = sample_vertices[static_cast<std::size_t>(i)];
    base.segment<3>(3 * i) = vertex(v);
    normals[static_cast<std::size_t>(i)] = mesh_normals[v].normalized();
    centroid += vertex(v);
    nose_z = std::max(nose_z, vertex(v).z());
  }
  centroid /= static_cast<float>(n);
  // Point-to-plane rows of the weight solve: n_i . (B_i w). With the normals of the neutral
  // they do not depend on the pose (n_camera . R B_i w = n_model . B_i w).
  normal_rows.resize(n, k);
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3f& nn = normals[static_cast<std::size_t>(i)];
    normal_rows.row(i) = nn.x() * expression_at_samples.row(3 * i) +
                         nn.y() * expression_at_samples.row(3 * i + 1) +
                         nn.z() * expression_at_samples.row(3 * i + 2);
  }
  landmark_base.resize(3 * 68);
  for (int l = 0; l < 68; ++l) landmark_base.segment<3>(3 * l) = vertex(m.landmark_vertices[l]);
  landmark_base += landmark_offset;
  // Depth signal of each shape: H0_jj = sum_i (n_i . B_ij)^2. Shapes far below the median are
  // nearly invisible in depth and would wander on noise, and the gaze shapes alias the lids
  // (see WeightSolverOptions::hold_gaze_shapes), so they get a strong prior to 0.
  const Eigen::VectorXf signal = normal_rows.colwise().squaredNorm().transpose();
  std::vector<float> sorted(signal.data(), signal.data() + k);
  std::nth_element(sorted.begin(), sorted.begin() + k / 2, sorted.end());
  const float median = sorted[static_cast<std::size_t>(k / 2)];
  shape_ridge.resize(k);
  signal_median = median;
  full_signal = signal.cwiseMax(1e-6f);
  seen_fraction = ShapeVector::Ones(k);
  weak_shapes.clear();
  for (int j = 0; j < k; ++j) {
    const bool weak = (hold_gaze_shapes && gaze_shape[static_cast<std::size_t>(j)]) ||
                      signal[j] < weak_shape_fraction * median;
    shape_ridge[j] = ridge + (weak ? weak_shape_ridge * median : 0.0f);
    if (weak) weak_shapes.push_back(j);
  }
  update_current(weights);
}

Result<void> SubjectRig::load(const TrackerRig& rig, const ShapeVector& weights) {
  const FaceModel& m = *model;
  const std::size_t size = static_cast<std::size_t>(3 * m.vertex_count);
  if (rig.neutral.size() != size) {
    return fail("tracking: the rig's neutral has " + std::to_string(rig.neutral.size() / 3) +
                " vertices, the face model " + std::to_string(m.vertex_count) +
                "; only rigs in the face model's topology can be tracked");
  }
  for (const auto& [index, shape] : rig.shapes) {
    if (index < 0 || index >= k) {
      return fail("tracking: rig shape index " + std::to_string(index) +
                  " is not one of the model's " + std::to_string(k) + " fitting shapes");
    }
    if (shape.size() != size) {
      return fail("tracking: rig shape '" + m.expression_names[static_cast<std::size_t>(index)] +
                  "' does not have the neutral's vertex count");
    }
  }
  expression_at_samples = model_expression_at_samples;
  expression_at_landmarks = model_expression_at_landmarks;
  auto replace = [&](auto& out, std::span<const std::uint32_t> vertices, int j,
                     std::span<const float> shape) {
    for (std::size_t i = 0; i < vertices.size(); ++i) {
      for (int a = 0; a < 3; ++a) {
        const std::size_t c = 3 * vertices[i] + static_cast<std::size_t>(a);
        out(3 * static_cast<int>(i) + a, j) = shape[c] - rig.neutral[c];
      }
    }
  };
  for (const auto& [index, shape] : rig.shapes) {
    replace(expression_at_samples, sample_vertices, index, shape);
    replace(expression_at_landmarks, m.landmark_vertices, index, shape);
  }
  custom_rig = true;
  identity.assign(static_cast<std::size_t>(modes), 0.0f);
  mesh_scratch.assign(rig.neutral.begin(), rig.neutral.end());
  landmark_offset.setZero();
  finish(weights);
  return success();
}

}  // namespace fb
