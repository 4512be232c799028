#include "algo/calibration/checkerboard_solver.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <Eigen/Dense>
#include <Eigen/Geometry>

namespace fb {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;
constexpr int kGlobal = 6;      // dx, dy, rotation_deg, depth_scale, inverse offset /m, edge offset
constexpr double kHuber = 3.0;  // in sigmas

struct State {
  std::vector<RigidPose> poses;
  RegistrationCorrection correction;
  double edge_offset = 1.0;
};

using Row = Eigen::Matrix<double, 1, 12>;  // 6 pose (rotation, translation) + 6 global

// Normal equations over all views' poses and the global parameters.
struct Normal {
  explicit Normal(int views) : size(6 * views + kGlobal) {
    h.setZero(size, size);
    g.setZero(size);
  }
  int size;
  Eigen::MatrixXd h;
  Eigen::VectorXd g;
  double cost = 0.0;

  // A residual r (already divided by its sigma) and its Jacobian row.
  void add(int view, double r, const Row& j) {
    const double a = std::abs(r);
    const double w = a <= kHuber ? 1.0 : kHuber / a;
    cost += a <= kHuber ? 0.5 * r * r : kHuber * (a - 0.5 * kHuber);
    int index[12];
    for (int k = 0; k < 6; ++k) index[k] = 6 * view + k, index[6 + k] = size - kGlobal + k;
    for (int p = 0; p < 12; ++p) {
      if (j[p] == 0.0) continue;
      g[index[p]] += w * j[p] * r;
      for (int q = 0; q < 12; ++q) h(index[p], index[q]) += w * j[p] * j[q];
    }
  }
};

Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

// Projection of a board point and d(u, v) / d(rotation increment, translation).
Eigen::Vector2d project(const PinholeIntrinsics& k, const RigidPose& pose, const Eigen::Vector3d& x,
                        Eigen::Matrix<double, 2, 6>* jacobian, Eigen::Vector3d* camera_point) {
  const Eigen::Vector3d rx = pose.rotation * x;
  const Eigen::Vector3d p = rx + pose.translation;
  if (camera_point != nullptr) *camera_point = p;
  if (jacobian != nullptr) {
    Eigen::Matrix<double, 2, 3> jp;
    jp << k.fx / p.z(), 0, -k.fx * p.x() / (p.z() * p.z()), 0, k.fy / p.z(),
        -k.fy * p.y() / (p.z() * p.z());
    jacobian->leftCols<3>() = -jp * skew(rx);
    jacobian->rightCols<3>() = jp;
  }
  return k.project(p);
}

double corrected_depth(const RegistrationCorrection& c, double table_mm, double* d_scale,
                       double* d_offset) {
  const double inverse = 1.0 / (c.depth_scale * table_mm) + c.inverse_depth_offset_per_m / 1000.0;
  const double z = 1.0 / inverse;
  if (d_scale != nullptr) *d_scale = z * z / (c.depth_scale * c.depth_scale * table_mm);
  if (d_offset != nullptr) *d_offset = -z * z / 1000.0;
  return z;
}

struct Problem {
  const BoardSpec& board;
  const RegistrationModel& model;
  const PinholeIntrinsics& k;
  std::span<const BoardView> views;
  const CheckerboardOptions& options;
  std::vector<Eigen::Vector3d> corners;  // board frame
  std::vector<Eigen::Vector3d> outline;  // board frame
};

// Corner j of view v: adds its two residuals; returns the colour error (px).
double add_corner(const Problem& pb, const State& s, int v, int j, Normal* normal) {
  Eigen::Matrix<double, 2, 6> juv;
  Eigen::Vector3d p;
  const Eigen::Vector2d uv = project(pb.k, s.poses[v], pb.corners[j], &juv, &p);
  Eigen::Vector2d q;
  Eigen::Matrix2d jr;
  if (!pb.model.rectified(uv.x(), uv.y(), q, &jr)) return -1.0;
  double dpar = 0.0;
  const double par = pb.model.parallax(p.z(), &dpar);
  const auto& c = s.correction;
  const double a = c.rotation_deg * kDeg, ca = std::cos(a), sa = std::sin(a);
  Eigen::Matrix2d rot, drot;
  rot << ca, -sa, sa, ca;
  drot << -sa, -ca, ca, -sa;
  const Eigen::Vector2d centred = q - RegistrationModel::centre();
  const Eigen::Vector2d color =
      RegistrationModel::centre() + rot * centred + Eigen::Vector2d(c.dx_px + par, c.dy_px);
  const Eigen::Vector2d error = color - pb.views[v].corners_color[j];
  if (normal != nullptr) {
    Eigen::Matrix<double, 2, 6> jpose = rot * jr * juv;
    // Parallax: d z / d(pose) is the third row of dP/d(pose).
    Eigen::Matrix<double, 1, 6> dz;
    dz << -(skew(s.poses[v].rotation * pb.corners[j])).row(2), 0, 0, 1;
    jpose.row(0) += dpar * dz;
    const Eigen::Vector2d drotation = drot * centred * kDeg;
    for (int axis = 0; axis < 2; ++axis) {
      Row row = Row::Zero();
      row.head<6>() = jpose.row(axis) / pb.options.corner_sigma_px;
      row[6 + axis] = 1.0 / pb.options.corner_sigma_px;
      row[8] = drotation[axis] / pb.options.corner_sigma_px;
      normal->add(v, error[axis] / pb.options.corner_sigma_px, row);
    }
  }
  return error.norm();
}

// Depth sample i of view v; returns the depth error (mm).
double add_depth(const Problem& pb, const State& s, int v, const Eigen::Vector3f& sample,
                 Normal* normal) {
  const RigidPose& pose = s.poses[v];
  const Eigen::Vector3d n = pose.rotation * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d ray((sample.x() - pb.k.cx) / pb.k.fx, (sample.y() - pb.k.cy) / pb.k.fy,
                            1.0);
  const double nr = n.dot(ray), nt = n.dot(pose.translation);
  const double plane_z = nt / nr;
  double d_scale = 0.0, d_offset = 0.0;
  const double z = corrected_depth(s.correction, sample.z(), &d_scale, &d_offset);
  const double error = z - plane_z;
  if (normal != nullptr) {
    const double sigma = pb.options.depth_sigma_at_1m_mm * (z / 1000.0) * (z / 1000.0);
    Row row = Row::Zero();
    // d plane_z / d rotation increment w: n -> n + w x n.
    row.head<3>() = -(n.cross(pose.translation) / nr - plane_z * n.cross(ray) / nr) / sigma;
    row.segment<3>(3) = -n / nr / sigma;
    row[9] = d_scale / sigma;
    row[10] = d_offset / sigma;
    normal->add(v, error / sigma, row);
  }
  return error;
}

// Where the scan of an edge sample crosses the projected outline: the crossing and the edge.
struct Crossing {
  double position = 0.0;
  int edge = -1;
  double t = 0.0;
};

Crossing find_crossing(const std::vector<Eigen::Vector2d>& q, const EdgeSample& e) {
  const int a = e.axis, b = 1 - a;  // a: the scan's axis, b: the fixed coordinate's
  const double fixed = b == 0 ? e.u : e.v, along = a == 0 ? e.u : e.v;
  Crossing best;
  double best_distance = 1e9;
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector2d& p0 = q[k];
    const Eigen::Vector2d& p1 = q[(k + 1) % 4];
    const double span = p1[b] - p0[b];
    if (std::abs(span) < std::abs(p1[a] - p0[a])) continue;  // scans cross it at a shallow angle
    const double t = (fixed - p0[b]) / span;
    if (t < 0.02 || t > 0.98) continue;  // near a plate corner
    const double position = p0[a] + t * (p1[a] - p0[a]);
    if (std::abs(position - along) < best_distance) {
      best_distance = std::abs(position - along);
      best = {position, k, t};
    }
  }
  return best;
}

// The outline samples of view v; returns the sum of squared errors (px^2) and the count.
std::pair<double, int> add_edges(const Problem& pb, const State& s, int v, Normal* normal) {
  std::vector<Eigen::Vector2d> q(4);
  std::vector<Eigen::Matrix<double, 2, 6>> jq(4);
  for (int k = 0; k < 4; ++k) q[k] = project(pb.k, s.poses[v], pb.outline[k], &jq[k], nullptr);
  double sum = 0.0;
  int count = 0;
  const double sigma = pb.options.edge_sigma_px;
  for (const EdgeSample& e : pb.views[v].edges) {
    const Crossing c = find_crossing(q, e);
    if (c.edge < 0) continue;
    const int a = e.axis, b = 1 - a;
    const double along = a == 0 ? e.u : e.v;
    const double error = e.outward * (c.position - along) - s.edge_offset;
    if (std::abs(error) > 6.0) continue;  // another edge, a hand, a gap in the depth
    sum += error * error;
    ++count;
    if (normal == nullptr) continue;
    const Eigen::Vector2d& p0 = q[c.edge];
    const Eigen::Vector2d& p1 = q[(c.edge + 1) % 4];
    const double span = p1[b] - p0[b], slope = p1[a] - p0[a];
    // position = p0[a] + t (p1[a] - p0[a]), t = (fixed - p0[b]) / span.
    const Eigen::Matrix<double, 1, 6> d = (1.0 - c.t) * jq[c.edge].row(a) +
                                          c.t * jq[(c.edge + 1) % 4].row(a) +
                                          slope * (c.t - 1.0) / span * jq[c.edge].row(b) -
                                          slope * c.t / span * jq[(c.edge + 1) % 4].row(b);
    Row row = Row::Zero();
    row.head<6>() = e.outward * d / sigma;
    row[11] = -1.0 / sigma;
    normal->add(v, error / sigma, row);
  }
  return {sum, count};
}

Normal build_normal(const Problem& pb, const State& s) {
  Normal normal(static_cast<int>(pb.views.size()));
  for (int v = 0; v < static_cast<int>(pb.views.size()); ++v) {
    for (int j = 0; j < pb.board.corner_count(); ++j) add_corner(pb, s, v, j, &normal);
    for (const auto& sample : pb.views[v].depth) add_depth(pb, s, v, sample, &normal);
    add_edges(pb, s, v, &normal);
  }
  return normal;
}

State apply_step(const State& s, const Eigen::VectorXd& step) {
  State next = s;
  for (std::size_t v = 0; v < s.poses.size(); ++v) {
    const Eigen::Vector3d w = step.segment<3>(6 * static_cast<long>(v));
    const double angle = w.norm();
    const Eigen::Quaterniond dq = angle > 0
                                      ? Eigen::Quaterniond(Eigen::AngleAxisd(angle, w / angle))
                                      : Eigen::Quaterniond::Identity();
    next.poses[v].rotation = (dq * s.poses[v].rotation).normalized();
    next.poses[v].translation += step.segment<3>(6 * static_cast<long>(v) + 3);
  }
  const long g = step.size() - kGlobal;
  next.correction.dx_px += step[g];
  next.correction.dy_px += step[g + 1];
  next.correction.rotation_deg += step[g + 2];
  next.correction.depth_scale += step[g + 3];
  next.correction.inverse_depth_offset_per_m += step[g + 4];
  next.edge_offset += step[g + 5];
  return next;
}

// Board pose from the colour corners traced back to the depth image under `correction` and
// onto the depth plane (table units), then scaled to metric by `scale`.
Result<RigidPose> initial_pose(const Problem& pb, const BoardView& view,
                               const RegistrationCorrection& correction, double& scale_out) {
  const Eigen::Vector3d plane = view.inverse_depth_plane;
  auto depth_of = [&](double u, double v) { return 1.0 / plane.dot(Eigen::Vector3d(u, v, 1.0)); };
  // Start from the middle of the plate in depth (the plane is fitted there).
  Eigen::Vector2d start = Eigen::Vector2d::Zero();
  for (const auto& d : view.depth) start += Eigen::Vector2d(d.x(), d.y()) / view.depth.size();
  std::vector<Eigen::Vector3d> board_points, depth_points;
  for (int j = 0; j < pb.board.corner_count(); ++j) {
    Eigen::Vector2d uv = start;
    if (!pb.model.depth_pixel_of(correction, view.corners_color[j], depth_of, uv)) continue;
    board_points.push_back(pb.corners[j]);
    depth_points.push_back(pb.k.unproject(uv.x(), uv.y(), depth_of(uv.x(), uv.y())));
  }
  if (board_points.size() < 6)
    return fail("the board's corners do not map back into the depth image");
  Eigen::Matrix3Xd src(3, board_points.size()), dst(3, board_points.size());
  for (std::size_t j = 0; j < board_points.size(); ++j) {
    src.col(static_cast<long>(j)) = board_points[j];
    dst.col(static_cast<long>(j)) = depth_points[j];
  }
  const Eigen::Matrix4d t = Eigen::umeyama(src, dst, true);
  const double scale = t.topLeftCorner<3, 3>().col(0).norm();
  RigidPose pose;
  pose.rotation = Eigen::Quaterniond(t.topLeftCorner<3, 3>() / scale).normalized();
  pose.translation = t.topRightCorner<3, 1>() / scale;
  scale_out = scale;
  return pose;
}

// Poses and a first correction: the shift from where the depth outline says the boards are.
Result<State> initialise(const Problem& pb) {
  State s;
  const int n = static_cast<int>(pb.views.size());
  for (int round = 0; round < 4; ++round) {
    s.poses.clear();
    double inverse_scale_sum = 0.0;
    for (const auto& view : pb.views) {
      double scale = 1.0;
      auto pose = initial_pose(pb, view, s.correction, scale);
      if (!pose) return pose.failure();
      s.poses.push_back(*pose);
      inverse_scale_sum += 1.0 / scale;
    }
    if (round == 0) s.correction.depth_scale = inverse_scale_sum / n;
    // Per view: how far the projected outline sits from the depth outline (depth px).
    Eigen::Vector2d shift = Eigen::Vector2d::Zero();
    for (int v = 0; v < n; ++v) {
      std::vector<Eigen::Vector2d> q(4);
      for (int k = 0; k < 4; ++k) q[k] = project(pb.k, s.poses[v], pb.outline[k], nullptr, nullptr);
      Eigen::Vector2d sum = Eigen::Vector2d::Zero(), count = Eigen::Vector2d::Zero();
      for (const EdgeSample& e : pb.views[v].edges) {
        const Crossing c = find_crossing(q, e);
        if (c.edge < 0) continue;
        const double along = e.axis == 0 ? e.u : e.v;
        sum[e.axis] += c.position - (along + e.outward * s.edge_offset);
        count[e.axis] += 1.0;
      }
      if (count.minCoeff() < 10) return fail("the plate outline does not match the board");
      shift += pb.model.mean_jacobian() * sum.cwiseQuotient(count) / n;
    }
    s.correction.dx_px += shift.x();
    s.correction.dy_px += shift.y();
  }
  return s;
}

}  // namespace

Result<CheckerboardResult> solve_checkerboard(const BoardSpec& board,
                                              const RegistrationModel& model,
                                              const PinholeIntrinsics& k,
                                              std::span<const BoardView> views,
                                              const CheckerboardOptions& options) {
  if (static_cast<int>(views.size()) < options.min_views) {
    return fail("only " + std::to_string(views.size()) + " usable board views; at least " +
                std::to_string(options.min_views) +
                " are needed (more, spread over the image "
                "and over 0.6-1.5 m, give a better calibration)");
  }
  Problem pb{board, model, k, views, options, {}, board.plate_outline()};
  for (int j = 0; j < board.corner_count(); ++j) pb.corners.push_back(board.corner(j));
  auto initial = initialise(pb);
  if (!initial) return initial.failure();
  State s = *initial;
  Normal normal = build_normal(pb, s);
  double lambda = 1e-3;
  int iteration = 0;
  for (; iteration < options.max_iterations; ++iteration) {
    Eigen::MatrixXd h = normal.h;
    h.diagonal() += lambda * normal.h.diagonal() + Eigen::VectorXd::Constant(h.rows(), 1e-9);
    const Eigen::VectorXd step = h.ldlt().solve(-normal.g);
    const State trial = apply_step(s, step);
    Normal trial_normal = build_normal(pb, trial);
    if (trial_normal.cost < normal.cost) {
      const double gain = normal.cost - trial_normal.cost;
      s = trial;
      normal = std::move(trial_normal);
      lambda = std::max(lambda / 4.0, 1e-7);
      if (gain < 1e-6 * normal.cost) break;
    } else {
      lambda *= 8.0;
      if (lambda > 1e8) break;
    }
  }

  CheckerboardResult result;
  result.correction = s.correction;
  result.edge_offset_px = s.edge_offset;
  result.iterations = iteration;
  double color_sum = 0.0, depth_sum = 0.0, edge_sum = 0.0;
  long color_n = 0, depth_n = 0, edge_n = 0;
  for (int v = 0; v < static_cast<int>(views.size()); ++v) {
    CheckerboardViewResidual r;
    r.camera_from_board = s.poses[v];
    double cs = 0.0, ds = 0.0;
    int cn = 0;
    for (int j = 0; j < board.corner_count(); ++j) {
      const double e = add_corner(pb, s, v, j, nullptr);
      if (e >= 0.0) cs += e * e, ++cn;
    }
    for (const auto& sample : views[v].depth) {
      const double e = add_depth(pb, s, v, sample, nullptr);
      ds += e * e;
    }
    const auto [es, en] = add_edges(pb, s, v, nullptr);
    r.color_px_rms = cn > 0 ? std::sqrt(cs / cn) : 0.0;
    r.depth_mm_rms = views[v].depth.empty() ? 0.0 : std::sqrt(ds / views[v].depth.size());
    r.edge_px_rms = en > 0 ? std::sqrt(es / en) : 0.0;
    color_sum += cs, depth_sum += ds, edge_sum += es;
    color_n += cn, depth_n += static_cast<long>(views[v].depth.size()), edge_n += en;
    result.views.push_back(r);
  }
  result.color_px_rms = color_n > 0 ? std::sqrt(color_sum / color_n) : 0.0;
  result.depth_mm_rms = depth_n > 0 ? std::sqrt(depth_sum / depth_n) : 0.0;
  result.edge_px_rms = edge_n > 0 ? std::sqrt(edge_sum / edge_n) : 0.0;
  if (!std::isfinite(result.color_px_rms) || !std::isfinite(result.correction.depth_scale) ||
      result.color_px_rms > 3.0) {
    return fail("the calibration did not converge (colour corners off by " +
                std::string(std::isfinite(result.color_px_rms) ? std::to_string(result.color_px_rms)
                                                               : "an undefined amount") +
                " px rms); check that the --board size matches the printed board");
  }
  return result;
}

double registration_difference_px(const RegistrationCorrection& a,
                                  const RegistrationCorrection& b) {
  double worst = 0.0;
  for (const Eigen::Vector2d& p :
       {Eigen::Vector2d(319.5, 239.5), Eigen::Vector2d(0, 0), Eigen::Vector2d(639, 0),
        Eigen::Vector2d(0, 479), Eigen::Vector2d(639, 479)}) {
    worst =
        std::max(worst, (RegistrationModel::apply(a, p) - RegistrationModel::apply(b, p)).norm());
  }
  return worst;
}

double depth_law_ratio(const RegistrationCorrection& estimate, const RegistrationCorrection& truth,
                       double true_mm) {
  // The table depth the unit reports for true_mm, then the estimate's depth for it.
  const double table =
      1.0 / (truth.depth_scale * (1.0 / true_mm - truth.inverse_depth_offset_per_m / 1000.0));
  return estimate.corrected_mm(table) / true_mm;
}

}  // namespace fb
