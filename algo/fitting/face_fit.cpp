#include "algo/fitting/face_fit.hpp"
#include "algo/core/clock.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <Eigen/SparseCholesky>

#include "algo/fitting/fit_correspondence.hpp"
#include "algo/fitting/mesh_ops.hpp"
#include "algo/render/rasterizer.hpp"

namespace fb {

using namespace fitting_detail;

namespace {

using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// Gate for the reported residuals (initial and final alike, so they compare).
constexpr double kMetricGateMm = 10.0;

Eigen::Matrix3d skew(const Eigen::Vector3d& a) {
  Eigen::Matrix3d m;
  m << 0, -a.z(), a.y(), a.z(), 0, -a.x(), -a.y(), a.x(), 0;
  return m;
}

// Rigid transform (Kabsch/Umeyama without scale) mapping src onto dst.
bool procrustes(const std::vector<Eigen::Vector3d>& src, const std::vector<Eigen::Vector3d>& dst,
                Eigen::Matrix3d& r, Eigen::Vector3d& t) {
  if (src.size() < 3) return false;
  Eigen::Matrix3Xd a(3, src.size()), b(3, dst.size());
  for (std::size_t i = 0; i < src.size(); ++i) {
    a.col(static_cast<Eigen::Index>(i)) = src[i];
    b.col(static_cast<Eigen::Index>(i)) = dst[i];
  }
  const Eigen::Matrix4d m = Eigen::umeyama(a, b, false);
  r = m.topLeftCorner<3, 3>();
  t = m.topRightCorner<3, 1>();
  return r.allFinite() && t.allFinite();
}

// Per-vertex residuals against the depth, and their RMS over the fitting vertices.
void residuals(const FaceModel& model, const FitTarget& target, const Points& x,
               std::span<const std::uint32_t> triangles, const std::vector<char>& vis,
               std::vector<float>& out, double& rms, int& count) {
  const Points vn = vertex_normals(x, triangles);
  out.assign(static_cast<std::size_t>(x.rows()), std::numeric_limits<float>::quiet_NaN());
  const double cos_min = std::cos(70.0 * M_PI / 180.0);
  for (Eigen::Index i = 0; i < std::min<Eigen::Index>(x.rows(), model.face_vertex_count); ++i) {
    if (!vis[static_cast<std::size_t>(i)]) continue;
    Correspondence c;
    if (correspond(target, x.row(i).transpose(), vn.row(i).transpose(), kMetricGateMm, cos_min, c))
      out[static_cast<std::size_t>(i)] = static_cast<float>(c.n.dot(x.row(i).transpose() - c.q));
  }
  double sum = 0;
  count = 0;
  for (std::uint32_t v : model.fitting_vertices) {
    const float r = out[v];
    if (std::isnan(r)) continue;
    sum += static_cast<double>(r) * r;
    ++count;
  }
  rms = count > 0 ? std::sqrt(sum / count) : kNaN;
}

// A fit without a single depth sample within the metric gate has no residual to report (the
// RMS would be NaN): the depth there is missing or far from where the landmarks put the face.
Result<void> check_depth_reached(int correspondences) {
  if (correspondences > 0) return success();
  return fail("fit: no depth sample lies within " +
              std::to_string(static_cast<int>(kMetricGateMm)) +
              " mm of the fitted face (the depth image has no surface where the landmarks put "
              "the face); check that the face is in the depth camera's view and range and that "
              "depth and colour are registered, then record again");
}

void landmark_residuals(const FitTarget& target, const Points& x,
                        const std::array<int, kFitLandmarkCount>& verts,
                        std::array<double, kFitLandmarkCount>& out) {
  for (int l = 0; l < kFitLandmarkCount; ++l) {
    const FitLandmark& lm = target.landmarks[static_cast<std::size_t>(l)];
    const Eigen::Vector3d p = x.row(verts[static_cast<std::size_t>(l)]).transpose();
    if (!lm.valid) {
      out[static_cast<std::size_t>(l)] = kNaN;
    } else if (lm.point && !is_contour_landmark(l)) {
      out[static_cast<std::size_t>(l)] = (p - *lm.point).norm();
    } else {
      const Eigen::Vector3d d = ray(target.intrinsics, lm.pixel).normalized();
      out[static_cast<std::size_t>(l)] = (p - d * d.dot(p)).norm();
    }
  }
}

RigidPose to_pose(const Eigen::Matrix3d& r, const Eigen::Vector3d& t) {
  RigidPose p;
  p.rotation = Eigen::Quaterniond(r).normalized();
  p.translation = t;
  return p;
}

// Interior landmarks with a 3D point, as (landmark index, point).
std::vector<int> interior_3d(const FitTarget& target) {
  std::vector<int> out;
  for (int l = 17; l < kFitLandmarkCount; ++l) {
    const FitLandmark& lm = target.landmarks[static_cast<std::size_t>(l)];
    if (lm.valid && lm.point) out.push_back(l);
  }
  return out;
}

Result<void> check_ready(const FaceModel& model, const FitTarget& target) {
  if (model.vertex_count <= 0 || model.fitting_vertices.empty())
    return fail("fit: the face model is empty");
  if (target.depth_mm.empty()) return fail("fit: the depth map is empty");
  if (target.normals.width != target.depth_mm.width ||
      target.normals.height != target.depth_mm.height)
    return fail("fit: the target has no normals; call prepare_fit_target() first");
  if (interior_3d(target).size() < 6)
    return fail(
        "fit: fewer than 6 interior landmarks have depth (no face found, or no depth in "
        "the face region)");
  if (target.landmark_vertices)
    for (std::uint32_t v : *target.landmark_vertices)
      if (v >= static_cast<std::uint32_t>(model.vertex_count))
        return fail("fit: the landmark convention names vertex " + std::to_string(v) +
                    ", which this face model (" + std::to_string(model.vertex_count) +
                    " vertices) does not have; rebuild the landmark embedding for this model");
  return success();
}

// `vertices` without those below the chin point of `v` (the neck): the neck lies outside the
// face region the neutral fit shapes, so its identity is not fitted to the subject, and an
// open jaw drags and covers it; where the target's depth reaches under the chin it tilted the
// expression's pose.
std::vector<std::uint32_t> above_chin(const FaceModel& model, const Points& v,
                                      std::span<const std::uint32_t> vertices) {
  const double chin = v(model.landmark_vertices[8], 1);
  const double up = v(model.landmark_vertices[19], 1) > chin ? 1.0 : -1.0;
  std::vector<std::uint32_t> out;
  out.reserve(vertices.size());
  for (std::uint32_t i : vertices)
    if (up * (v(i, 1) - chin) >= 0.0) out.push_back(i);
  return out;
}

}  // namespace

Eigen::Vector3d FitResult::camera_vertex(int i) const {
  const Eigen::Vector3d v(vertices[static_cast<std::size_t>(3 * i)],
                          vertices[static_cast<std::size_t>(3 * i + 1)],
                          vertices[static_cast<std::size_t>(3 * i + 2)]);
  return camera_from_model.apply(v);
}

namespace {

// Point-to-plane ICP on the rigid vertices above the chin, with the start's landmarks (weight
// as Efea), from (r, t). Returns the pose's truncated residual over those vertices: each
// contributes min(res^2, 4^2) mm^2, one without a surface within 4 mm the full 16, so a pose
// that slid off the face does not score well by matching less of it.
double icp_rigid(const FaceModel& model, const FitTarget& target, const Points& v,
                 const Points& n_model, const std::vector<std::uint32_t>& rigid,
                 const std::vector<int>& interior, int iterations, Eigen::Matrix3d& r,
                 Eigen::Vector3d& t) {
  const double cos_min = std::cos(70.0 * M_PI / 180.0);
  // `iterations` steps with the gate shrinking from 15 to 4 mm, then steps at 4 mm until the
  // pose settles: from a landmark Procrustes start a few degrees off, 8 steps left half the
  // expression captures 2-4 deg off, which the refinement then baked into the mesh.
  constexpr int kMaxSettleSteps = 40;
  const int total = iterations > 0 ? iterations + kMaxSettleSteps : 0;
  for (int it = 0; it < total; ++it) {
    Eigen::Matrix<double, 6, 6> h = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> g = Eigen::Matrix<double, 6, 1>::Zero();
    const double gate = std::max(
        4.0, 15.0 * (1.0 - std::min(it, iterations - 1) / std::max(1.0, iterations - 1.0)));
    for (std::uint32_t i : rigid) {
      const Eigen::Vector3d a = r * v.row(i).transpose();
      const Eigen::Vector3d x = a + t;
      Correspondence c;
      if (!correspond(target, x, r * n_model.row(i).transpose(), gate, cos_min, c)) continue;
      Eigen::Matrix<double, 6, 1> j;
      j << a.cross(c.n), c.n;
      const double res = c.n.dot(x - c.q);
      h += j * j.transpose();
      g += j * res;
    }
    for (int l : interior) {
      const Eigen::Vector3d a = r * v.row(marked_vertex(model, target, l)).transpose();
      const Eigen::Vector3d res = a + t - *target.landmarks[static_cast<std::size_t>(l)].point;
      Eigen::Matrix<double, 3, 6> j;
      j << -skew(a), Eigen::Matrix3d::Identity();
      h += 0.25 * j.transpose() * j;  // landmarks are noisier than depth: a light weight
      g += 0.25 * j.transpose() * res;
    }
    h.diagonal().array() += 1e-6;
    const Eigen::Matrix<double, 6, 1> d = h.ldlt().solve(-g);
    if (!d.allFinite()) break;
    const Eigen::Vector3d w = d.head<3>();
    const double angle = w.norm();
    if (angle > 0) r = Eigen::AngleAxisd(angle, w / angle).toRotationMatrix() * r;
    t += d.tail<3>();
    if (d.norm() < 1e-6) break;
    // Settled: below 0.001 deg and 1 um.
    if (it >= iterations && angle < 2e-5 && d.tail<3>().norm() < 1e-3) break;
  }
  double score = 0;
  for (std::uint32_t i : rigid) {
    const Eigen::Vector3d x = r * v.row(i).transpose() + t;
    Correspondence c;
    const bool hit = correspond(target, x, r * n_model.row(i).transpose(), 4.0, cos_min, c);
    score += hit ? std::min(16.0, std::pow(c.n.dot(x - c.q), 2)) : 16.0;
  }
  return score;
}

}  // namespace

Result<RigidPose> align_rigid(const FaceModel& model, const FitTarget& target,
                              std::span<const float> mesh, int iterations,
                              const std::optional<RigidPose>& initial,
                              std::span<const int> second_start,
                              std::span<const std::uint32_t> still_vertices) {
  if (auto ok = check_ready(model, target); !ok) return ok.failure();
  const Points v = to_points(mesh);
  const std::vector<int> interior = interior_3d(target);
  std::vector<std::vector<int>> starts{interior};
  if (!initial && iterations > 0 && !second_start.empty()) {
    std::vector<int> own;
    for (int l : second_start)
      if (std::find(interior.begin(), interior.end(), l) != interior.end()) own.push_back(l);
    if (own.size() >= 4) starts.push_back(std::move(own));
  }
  const Points n_model = vertex_normals(v, model.triangles);
  const std::vector<std::uint32_t> rigid = above_chin(
      model, v, still_vertices.empty() ? std::span(model.rigid_vertices) : still_vertices);
  double best = std::numeric_limits<double>::infinity();
  RigidPose out;
  for (const auto& start : starts) {
    Eigen::Matrix3d r;
    Eigen::Vector3d t;
    if (initial) {
      r = initial->rotation.toRotationMatrix();
      t = initial->translation;
    } else {
      std::vector<Eigen::Vector3d> src, dst;
      for (int l : start) {
        src.push_back(v.row(marked_vertex(model, target, l)).transpose());
        dst.push_back(*target.landmarks[static_cast<std::size_t>(l)].point);
      }
      if (!procrustes(src, dst, r, t)) return fail("fit: rigid alignment of the landmarks failed");
    }
    const double score = icp_rigid(model, target, v, n_model, rigid, start, iterations, r, t);
    if (score < best) {
      best = score;
      out = to_pose(r, t);
    }
  }
  return out;
}

namespace {

// Where the refinement pulls a vertex p with depth correspondence c: towards the foot of the
// perpendicular on the sample's tangent plane, the step scaled by the sample's confidence and a
// Cauchy weight on the plane residual. With the fixed matrix this has the weighted term's fixed
// point (the rest of the pull keeps the vertex where it is; see refine_system.hpp).
Eigen::Vector3d weighted_pull(const Eigen::Vector3d& p, const Correspondence& c,
                              double robust_scale_mm) {
  const double plane = c.n.dot(p - c.q);
  const double rs = robust_scale_mm > 0 ? plane / robust_scale_mm : 0.0;
  if (behind_hair(c, p)) return p;
  return p - (c.confidence / (1.0 + rs * rs)) * plane * c.n;
}

}  // namespace

Result<FitResult> refine_fit(const FaceModel& model, const FitTarget& target,
                             std::span<const float> start, const RigidPose& camera_from_model,
                             const RefineOptions& o, const RefineSystem* shared) {
  if (auto ok = check_ready(model, target); !ok) return ok.failure();
  if (start.size() != static_cast<std::size_t>(model.vertex_count) * 3)
    return fail("refine: the start mesh has the wrong vertex count");
  const auto t0 = Clock::now();
  const Eigen::Matrix3d r = camera_from_model.rotation.toRotationMatrix();
  const Eigen::Vector3d t = camera_from_model.translation;
  const Points x0 = posed(to_points(start), r, t);
  const Eigen::Index n = x0.rows();

  FitResult res;
  res.camera_from_model = camera_from_model;
  res.initial_vertices.assign(start.begin(), start.end());
  const std::vector<char> vis0 = visible_vertices(target, x0, model.triangles);
  residuals(model, target, x0, model.triangles, vis0, res.initial_vertex_residual_mm,
            res.rms_to_depth_mm_initial, res.depth_correspondences);

  // The normal matrix: the subject's shared one when its weights are these, else this fit's
  // own, from the start mesh's Laplacian.
  const double cos_min = std::cos(o.max_normal_angle_deg * M_PI / 180.0);
  const RefineSystemOptions matrix_options = refine_system_options(o);
  std::optional<RefineSystem> own;
  const RefineSystem* system = shared;
  if (!system || !(system->options() == matrix_options)) {
    auto made = RefineSystem::create(model, x0, matrix_options);
    if (!made) return made.failure();
    own.emplace(std::move(*made));
    system = &*own;
  }
  const Eigen::SparseMatrix<double>& lap = system->laplacian();
  const std::vector<int>& free = system->free_vertices();
  const Eigen::Index nf = static_cast<Eigen::Index>(free.size());
  const double anchor = system->options().anchor;

  // Elap: target lengths |L x0| of the start mesh, directions of the current one.
  const Points lx0 = lap * x0;
  const Eigen::VectorXd delta = lx0.rowwise().norm();
  const auto lm_verts = landmark_vertices(model, target, x0);

  Points x = x0;
  Points lt(n, 3), rhs(nf, 3);
  std::vector<Eigen::Vector3d> depth_target(static_cast<std::size_t>(nf));
  std::vector<char> has_target(static_cast<std::size_t>(nf), 0);
  for (int it = 0; it < o.iterations; ++it) {
    const Points vn = vertex_normals(x, model.triangles);
    const Points lx = lap * x;
    for (Eigen::Index i = 0; i < n; ++i) {
      const double len = lx.row(i).norm();
      lt.row(i) = len > 1e-9 ? Eigen::RowVector3d(lx.row(i) * (delta[i] / len))
                             : Eigen::RowVector3d(lx0.row(i));
    }
    system->laplacian_rhs(lt, x0, rhs);
    // Epos: closest point on the depth surface's tangent plane (foot of the perpendicular),
    // re-found from the current mesh every reassociate_every steps; a vertex without one is
    // pulled to where it is.
    const bool reassociate = it % std::max(1, o.reassociate_every) == 0;
    for (Eigen::Index f = 0; f < nf; ++f) {
      const int v = free[static_cast<std::size_t>(f)];
      const Eigen::Vector3d p = x.row(v).transpose();
      rhs.row(f) += anchor * x0.row(v);
      if (!system->has_position_term(v)) continue;
      if (reassociate) {
        Correspondence c;
        has_target[static_cast<std::size_t>(f)] =
            vis0[static_cast<std::size_t>(v)] &&
            correspond(target, p, vn.row(v).transpose(), o.max_distance_mm, cos_min, c);
        if (has_target[static_cast<std::size_t>(f)])
          depth_target[static_cast<std::size_t>(f)] = weighted_pull(p, c, o.robust_scale_mm);
      }
      rhs.row(f) +=
          o.w_pos *
          (has_target[static_cast<std::size_t>(f)] ? depth_target[static_cast<std::size_t>(f)] : p)
              .transpose();
    }
    // Efea, lagged (see refine_system.hpp): w_fea (goal - x), the pull capped at
    // landmark_huber_mm (Huber with a fixed matrix).
    for (int l = 0; l < kFitLandmarkCount; ++l) {
      const FitLandmark& lm = target.landmarks[static_cast<std::size_t>(l)];
      if (!lm.valid) continue;
      const int v = lm_verts[static_cast<std::size_t>(l)];
      // Only where A has a position term: elsewhere A^-1 barely damps smooth fields (eps), and
      // a lagged pull would be amplified instead of contracted.
      const int f = system->free_index(v);
      if (f < 0 || !system->has_position_term(v)) continue;
      const Eigen::Vector3d cur = x.row(v).transpose();
      Eigen::Vector3d goal;
      if (lm.point && !is_contour_landmark(l)) {
        goal = *lm.point;
      } else {  // 2D: closest point on the viewing ray
        const Eigen::Vector3d d = ray(target.intrinsics, lm.pixel).normalized();
        goal = d * d.dot(cur);
      }
      Eigen::Vector3d step = goal - cur;
      if (o.landmark_huber_mm > 0 && step.norm() > o.landmark_huber_mm)
        step *= o.landmark_huber_mm / step.norm();
      rhs.row(f) += o.w_fea * step.transpose();
    }
    system->solve(rhs);
    if (!rhs.allFinite()) return fail("refine: the solve diverged");
    for (Eigen::Index f = 0; f < nf; ++f) x.row(free[static_cast<std::size_t>(f)]) = rhs.row(f);
  }

  // Back to the model frame.
  const Points v_model = (x.rowwise() - t.transpose()) * r;
  from_points(v_model, res.vertices);
  residuals(model, target, x, model.triangles, visible_vertices(target, x, model.triangles),
            res.vertex_residual_mm, res.rms_to_depth_mm, res.depth_correspondences);
  if (auto ok = check_depth_reached(res.depth_correspondences); !ok) return ok.failure();
  res.landmark_vertex = lm_verts;
  landmark_residuals(target, x, lm_verts, res.landmark_residual_mm);
  res.times.refine_ms = ms_since(t0);
  return res;
}

RefineSystemOptions refine_system_options(const RefineOptions& o) {
  RefineSystemOptions m;
  m.w_pos = o.w_pos;
  m.w_lap = o.w_lap;
  m.margin_rings = o.margin_rings;
  return m;
}

Result<RefineSystem> model_refine_system(const FaceModel& model, const RefineOptions& o) {
  std::vector<float> mean(static_cast<std::size_t>(model.vertex_count) * 3);
  model.evaluate({}, {}, mean);
  return RefineSystem::create(model, to_points(mean), refine_system_options(o));
}

// The Gauss-Newton step of E1 from its weighted rows: (omega, dt, dc, da). Ecoef = 1/2 c^T c
// (the basis carries sigma) and 1/2 a^T a (each bump's amplitude in units of
// offset_amplitude_mm): Hessian w I, gradient w c.
static Result<Eigen::VectorXd> gauss_newton_step(const RowMatrix& j, const Eigen::VectorXd& res,
                                                 const Eigen::VectorXd& c, const Eigen::VectorXd& a,
                                                 double w_coef) {
  const Eigen::Index m = c.size(), nk = a.size(), unknowns = j.cols();
  Eigen::MatrixXd h = Eigen::MatrixXd::Zero(unknowns, unknowns);
  h.selfadjointView<Eigen::Lower>().rankUpdate(j.transpose());
  h = h.selfadjointView<Eigen::Lower>();
  Eigen::VectorXd g = j.transpose() * res;
  h.diagonal().segment(6, m + nk).array() += w_coef;
  g.segment(6, m) += w_coef * c;
  g.tail(nk) += w_coef * a;
  h.diagonal().head(6).array() += 1e-6;
  const Eigen::VectorXd d = h.ldlt().solve(-g);
  if (!d.allFinite()) return fail("fit: the least-squares step diverged");
  return d;
}

// fit_neutral()'s step 1, one Gauss-Newton round at x = r v + t: the step (omega, dt, dc, da).
static Result<Eigen::VectorXd> neutral_step(
    const FaceModel& model, const FitTarget& target, const NeutralFitOptions& o,
    const Eigen::VectorXd& c, const Eigen::Matrix3d& r, const Points& v, const Points& x,
    const Points& vn, const std::array<int, kFitLandmarkCount>& lm_verts,
    const std::vector<int>& interior, const std::vector<int>& depth_set,
    const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>& depth_basis,
    double gate, double w_fea, double cos_min, const OffsetBasis* offsets,
    const Eigen::VectorXd& a_off) {
  const int m = static_cast<int>(c.size());
  const int nk = offsets ? offsets->count : 0, unknowns = 6 + m + nk;
  const double amp = o.offset_amplitude_mm;
  const std::size_t stride = static_cast<std::size_t>(model.vertex_count) * 3;
  auto basis_row = [&](int v, int d, int k) {
    return static_cast<double>(model.identity_basis[static_cast<std::size_t>(k) * stride +
                                                    static_cast<std::size_t>(3 * v + d)]);
  };
  // Rows: 3 per interior landmark, 2 per contour landmark, 1 per depth correspondence; each
  // scaled by sqrt(2 w) so that J^T J + w_coef I is the Gauss-Newton matrix of E1.
  std::vector<Correspondence> corr;
  std::vector<int> corr_v, corr_slot;
  const std::vector<char> vis = visible_vertices(target, x, model.triangles);
  for (std::size_t slot = 0; slot < depth_set.size(); ++slot) {
    const int vtx = depth_set[slot];
    if (!vis[static_cast<std::size_t>(vtx)]) continue;
    Correspondence cc;
    if (correspond(target, x.row(vtx).transpose(), vn.row(vtx).transpose(), gate, cos_min, cc) &&
        (o.hair_weight > 0 || !behind_hair(cc, x.row(vtx).transpose()))) {
      corr.push_back(cc);
      corr_v.push_back(vtx);
      corr_slot.push_back(static_cast<int>(slot));
    }
  }
  // 2D rows: the contour, and interior points without depth (rims of eyes and mouth).
  std::vector<int> contour;
  for (int l = 0; l < kFitLandmarkCount; ++l) {
    const FitLandmark& lm = target.landmarks[static_cast<std::size_t>(l)];
    if (lm.valid && (is_contour_landmark(l) || !lm.point)) contour.push_back(l);
  }
  const Eigen::Index rows =
      static_cast<Eigen::Index>(3 * interior.size() + 2 * contour.size() + corr.size());
  // Row-major: every row is written whole (the offsets' columns zeroed first), and J^T J reads
  // it row by row.
  RowMatrix j(rows, unknowns);
  if (nk > 0) j.rightCols(nk).setZero();
  // The offsets' columns, on depth rows only (a landmark's error lies mostly along the surface,
  // which they cannot move, and a detector's bias would bend the face): a row of projection p
  // at vertex v reads (R^T p . n_v) A g_k(v).
  auto offset_cols = [&](Eigen::Index row, int vtx, const Eigen::Vector3d& rp, double s) {
    if (!offsets) return;
    const double pn =
        s * amp * rp.dot(offsets->normal[static_cast<std::size_t>(vtx)].cast<double>());
    for (const auto& e : offsets->of(static_cast<std::size_t>(vtx)))
      j(row, 6 + m + e.bump) = pn * e.weight;
  };
  Eigen::VectorXd res(rows);
  Eigen::Index row = 0;
  const double sf = std::sqrt(2.0 * w_fea), sp = std::sqrt(2.0 * o.w_pos);
  // Jacobian of x = R v + t w.r.t. (omega, dt, c): [-[Rv]x, I, R B_v]; a row of a projection
  // p (1 x 3) is [(Rv x p)^T, p, (R^T p)^T B_v].
  auto point_rows = [&](int vtx, const Eigen::MatrixXd& proj, const Eigen::VectorXd& r0, double s,
                        double huber_mm) {
    // Huber (IRLS): residuals beyond huber_mm get weight huber_mm / |r|, so one wrong
    // landmark cannot drag the whole face.
    if (huber_mm > 0 && r0.norm() > huber_mm) s *= std::sqrt(huber_mm / r0.norm());
    const Eigen::Vector3d a = r * v.row(vtx).transpose();
    for (Eigen::Index k = 0; k < proj.rows(); ++k) {
      const Eigen::Vector3d p = proj.row(k).transpose();
      const Eigen::Vector3d rp = r.transpose() * p;
      j.row(row).head<3>() = s * a.cross(p).transpose();
      j.row(row).segment<3>(3) = s * p.transpose();
      for (int mode = 0; mode < m; ++mode)
        j(row, 6 + mode) =
            s * (rp.x() * basis_row(vtx, 0, mode) + rp.y() * basis_row(vtx, 1, mode) +
                 rp.z() * basis_row(vtx, 2, mode));
      res[row] = s * r0[k];
      ++row;
    }
  };
  for (int l : interior) {
    const int vtx = lm_verts[static_cast<std::size_t>(l)];
    point_rows(vtx, Eigen::Matrix3d::Identity(),
               x.row(vtx).transpose() - *target.landmarks[static_cast<std::size_t>(l)].point, sf,
               o.landmark_huber_mm);
  }
  for (int l : contour) {
    // Image distance measured in mm at the vertex depth: r = [x - a z, y - b z] with
    // (a, b) the ray through the landmark; linear in x.
    const int vtx = lm_verts[static_cast<std::size_t>(l)];
    const Eigen::Vector3d d =
        ray(target.intrinsics, target.landmarks[static_cast<std::size_t>(l)].pixel);
    Eigen::Matrix<double, 2, 3> p;
    p << 1, 0, -d.x(), 0, 1, -d.y();
    point_rows(vtx, p, p * x.row(vtx).transpose(), sf, o.landmark_huber_mm);
  }
  // Depth rows from the gathered basis (contiguous per vertex).
  for (std::size_t k = 0; k < corr.size(); ++k) {
    const int vtx = corr_v[k];
    const Eigen::Vector3d& n = corr[k].n;
    const Eigen::Vector3d a = r * v.row(vtx).transpose();
    double sw = !behind_hair(corr[k], x.row(vtx).transpose()) ? sp
                : corr[k].along_face                          ? sp * std::sqrt(o.hair_weight)
                                                              : 0.0;
    if (o.robust_scale_mm > 0) {  // Cauchy (IRLS): the row's weight 1 / (1 + (r / s)^2)
      const double u = n.dot(x.row(vtx).transpose() - corr[k].q) / o.robust_scale_mm;
      sw /= std::sqrt(1.0 + u * u);
    }
    const Eigen::Vector3d rn = sw * (r.transpose() * n);
    j.row(row).head<3>() = sw * a.cross(n).transpose();
    j.row(row).segment<3>(3) = sw * n.transpose();
    const Eigen::Index g = 3 * static_cast<Eigen::Index>(corr_slot[k]);
    j.row(row).segment(6, m) = (rn.x() * depth_basis.row(g) + rn.y() * depth_basis.row(g + 1) +
                                rn.z() * depth_basis.row(g + 2))
                                   .cast<double>();
    offset_cols(row, vtx, r.transpose() * n, sw);
    res[row] = sw * n.dot(x.row(vtx).transpose() - corr[k].q);
    ++row;
  }
  return gauss_newton_step(j, res, c, a_off, o.w_coef);
}

// The offsets along the normal step 1 solves (NeutralFitOptions::offset_amplitude_mm), on the
// mean face; none when off.
static std::optional<OffsetBasis> neutral_offsets(const FaceModel& model,
                                                  const NeutralFitOptions& o) {
  if (o.offset_amplitude_mm <= 0) return std::nullopt;
  std::vector<float> mean(static_cast<std::size_t>(model.vertex_count) * 3);
  model.evaluate({}, {}, mean);
  return make_offset_basis(model, mean, model.fitting_vertices, o.offsets);
}

Result<FitResult> fit_neutral(const FaceModel& model, const FitTarget& target,
                              const NeutralFitOptions& o, const FitResult* initial,
                              const RefineSystem* model_system) {
  if (auto ok = check_ready(model, target); !ok) return ok.failure();
  const auto t0 = Clock::now();
  const int m = std::clamp(o.identity_modes, 0, model.identity_count);
  const int nv = model.vertex_count;
  const std::size_t stride = static_cast<std::size_t>(nv) * 3;

  // Identity basis gathered per vertex (rows 3i..3i+2), only for the vertices step 1 touches.
  std::vector<int> depth_set;
  for (std::size_t k = 0; k < model.fitting_vertices.size();
       k += static_cast<std::size_t>(std::max(1, o.depth_vertex_stride)))
    depth_set.push_back(static_cast<int>(model.fitting_vertices[k]));

  Eigen::VectorXd c = Eigen::VectorXd::Zero(m);
  Eigen::Matrix3d r;
  Eigen::Vector3d t;
  std::vector<float> mesh(stride);
  if (initial && initial->identity_coeffs.size() == static_cast<std::size_t>(m)) {
    for (int k = 0; k < m; ++k) c[k] = initial->identity_coeffs[static_cast<std::size_t>(k)];
    r = initial->camera_from_model.rotation.toRotationMatrix();
    t = initial->camera_from_model.translation;
  } else {
    model.evaluate({}, {}, mesh);
    auto pose = align_rigid(model, target, mesh, 0);
    if (!pose) return pose.failure();
    r = pose->rotation.toRotationMatrix();
    t = pose->translation;
  }
  std::vector<float> coeffs(static_cast<std::size_t>(m));
  const double cos_min = std::cos(o.max_normal_angle_deg * M_PI / 180.0);
  const std::vector<int> interior = interior_3d(target);
  // The identity basis of the depth vertices, gathered per vertex (rows 3s..3s+2 for
  // depth_set[s]): the model stores it mode by mode, which the per-row products would stride.
  Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> depth_basis(
      3 * static_cast<Eigen::Index>(depth_set.size()), m);
  for (int mode = 0; mode < m; ++mode) {
    const float* block = model.identity_basis.data() + static_cast<std::size_t>(mode) * stride;
    for (std::size_t slot = 0; slot < depth_set.size(); ++slot)
      for (int d = 0; d < 3; ++d)
        depth_basis(3 * static_cast<Eigen::Index>(slot) + d, mode) =
            block[3 * static_cast<std::size_t>(depth_set[slot]) + d];
  }
  std::array<int, kFitLandmarkCount> lm_verts{};
  const std::optional<OffsetBasis> offsets = neutral_offsets(model, o);
  Eigen::VectorXd a_off = Eigen::VectorXd::Zero(offsets ? offsets->count : 0);
  std::vector<double> a_mm(static_cast<std::size_t>(a_off.size()));
  auto evaluate = [&] {
    for (int k = 0; k < m; ++k) coeffs[static_cast<std::size_t>(k)] = static_cast<float>(c[k]);
    model.evaluate(coeffs, {}, mesh);
    if (!offsets) return;
    for (std::size_t k = 0; k < a_mm.size(); ++k)
      a_mm[k] = a_off[static_cast<Eigen::Index>(k)] * o.offset_amplitude_mm;
    add_offsets(*offsets, a_mm, mesh);
  };
  const int max_rounds = std::max(o.rounds, o.max_rounds);
  int rounds_run = 0;
  for (int round = 0; round < max_rounds; ++round) {
    rounds_run = round + 1;
    evaluate();
    const Points v = to_points(mesh);
    const Points x = posed(v, r, t);
    const Points vn = vertex_normals(x, model.triangles);
    lm_verts = landmark_vertices(model, target, x);
    const double f =
        o.rounds > 1 ? std::min(1.0, static_cast<double>(round) / (o.rounds - 1)) : 1.0;
    const double gate = o.max_distance_mm + f * (o.final_distance_mm - o.max_distance_mm);
    const double w_fea = o.w_fea + f * (o.w_fea_final - o.w_fea);

    auto step =
        neutral_step(model, target, o, c, r, v, x, vn, lm_verts, interior, depth_set, depth_basis,
                     gate, w_fea, cos_min, offsets ? &*offsets : nullptr, a_off);
    if (!step) return step.failure();
    const Eigen::VectorXd& d = *step;
    const Eigen::Vector3d w = d.head<3>();
    const double angle = w.norm();
    if (angle > 0) r = Eigen::AngleAxisd(angle, w / angle).toRotationMatrix() * r;
    t += d.segment<3>(3);
    c += d.segment(6, m);
    if (offsets) a_off += d.tail(offsets->count);
    const bool settled = (m == 0 || d.segment(6, m).cwiseAbs().maxCoeff() < o.settled_coeff) &&
                         d.segment<3>(3).norm() < o.settled_mm &&
                         angle * 100.0 < o.settled_mm;  // ~100 mm lever arm
    if (round + 1 >= o.rounds && settled) break;
  }
  evaluate();
  const RigidPose pose = to_pose(r, t);
  const double initial_ms = ms_since(t0);

  FitResult out;
  if (o.refine) {
    auto refined = refine_fit(model, target, mesh, pose, o.refine_options, model_system);
    if (!refined) return refined.failure();
    out = std::move(*refined);
  } else {
    out.vertices = mesh;
    out.initial_vertices = mesh;
    out.camera_from_model = pose;
    const Points x = posed(to_points(mesh), r, t);
    residuals(model, target, x, model.triangles, visible_vertices(target, x, model.triangles),
              out.vertex_residual_mm, out.rms_to_depth_mm, out.depth_correspondences);
    if (auto ok = check_depth_reached(out.depth_correspondences); !ok) return ok.failure();
    out.initial_vertex_residual_mm = out.vertex_residual_mm;
    out.rms_to_depth_mm_initial = out.rms_to_depth_mm;
    out.landmark_vertex = landmark_vertices(model, target, x);
    landmark_residuals(target, x, out.landmark_vertex, out.landmark_residual_mm);
  }
  out.identity_coeffs = coeffs;
  out.rounds = rounds_run;
  out.times.initial_ms = initial_ms;
  return out;
}

double mean_vertex_distance(std::span<const float> a, const RigidPose& pose_a,
                            std::span<const float> b, const RigidPose& pose_b,
                            std::span<const std::uint32_t> subset) {
  double sum = 0;
  int n = 0;
  for (std::uint32_t v : subset) {
    const std::size_t i = 3 * static_cast<std::size_t>(v);
    if (i + 2 >= a.size() || i + 2 >= b.size()) continue;
    const Eigen::Vector3d pa = pose_a.apply({a[i], a[i + 1], a[i + 2]});
    const Eigen::Vector3d pb = pose_b.apply({b[i], b[i + 1], b[i + 2]});
    sum += (pa - pb).norm();
    ++n;
  }
  return n > 0 ? sum / n : kNaN;
}

}  // namespace fb
