#include "algo/bilinear/image_fit.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <Eigen/SVD>

namespace fb {
namespace {

// The core restricted to the 68 landmark vertices: 204 x (Kexp * Kid), column b * Kid + a.
Eigen::MatrixXd landmark_core(const BilinearModel& m) {
  const int cols = m.id_knobs * m.exp_knobs;
  Eigen::MatrixXd c(204, cols);
  const std::size_t n = static_cast<std::size_t>(m.coordinate_count());
  for (int col = 0; col < cols; ++col)
    for (int k = 0; k < 68; ++k)
      for (int d = 0; d < 3; ++d)
        c(3 * k + d, col) =
            m.core[static_cast<std::size_t>(col) * n + 3 * m.landmark_vertices[k] + d];
  return c;
}

// Gaussian prior of a factor matrix's rows: mean and per-column variance.
struct Prior {
  Eigen::VectorXd mean;
  Eigen::VectorXd inverse_variance;
};
Prior row_prior(std::span<const float> factors, int rows, int cols) {
  const Eigen::Map<const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> u(
      factors.data(), rows, cols);
  Prior p;
  p.mean = u.cast<double>().colwise().mean().transpose();
  const Eigen::MatrixXd centred = u.cast<double>().rowwise() - p.mean.transpose();
  const Eigen::VectorXd var = centred.colwise().squaredNorm().transpose() / std::max(1, rows - 1);
  // A floor keeps knobs with (almost) no spread from making the system singular.
  const double floor = std::max(1e-12, 1e-6 * var.maxCoeff());
  p.inverse_variance = (var.array().max(floor)).inverse();
  return p;
}

// Contractions of the landmark core: with w_exp fixed -> 204 x Kid; with w_id fixed -> 204 x Kexp.
Eigen::MatrixXd by_expression(const Eigen::MatrixXd& c, int id_knobs, int exp_knobs,
                              const Eigen::VectorXd& w_exp) {
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(c.rows(), id_knobs);
  for (int b = 0; b < exp_knobs; ++b) out += w_exp[b] * c.middleCols(b * id_knobs, id_knobs);
  return out;
}
Eigen::MatrixXd by_identity(const Eigen::MatrixXd& c, int id_knobs, int exp_knobs,
                            const Eigen::VectorXd& w_id) {
  Eigen::MatrixXd out(c.rows(), exp_knobs);
  for (int b = 0; b < exp_knobs; ++b) out.col(b) = c.middleCols(b * id_knobs, id_knobs) * w_id;
  return out;
}

std::vector<int> valid_indices(const ImageLandmarks& l) {
  std::vector<int> out;
  for (int k = 0; k < 68; ++k)
    if (l.valid[static_cast<std::size_t>(k)] && l.points[static_cast<std::size_t>(k)].allFinite())
      out.push_back(k);
  return out;
}

// Affine camera by least squares, then the nearest scaled rotation.
WeakPerspectivePose affine_pose(const Eigen::VectorXd& x, const ImageLandmarks& l,
                                const std::vector<int>& use) {
  const int n = static_cast<int>(use.size());
  Eigen::MatrixXd a(n, 4);
  Eigen::MatrixXd b(n, 2);
  for (int r = 0; r < n; ++r) {
    const int k = use[static_cast<std::size_t>(r)];
    a.row(r) << x[3 * k], x[3 * k + 1], x[3 * k + 2], 1.0;
    b.row(r) = l.points[static_cast<std::size_t>(k)].transpose();
  }
  const Eigen::MatrixXd p = a.colPivHouseholderQr().solve(b).transpose();  // 2 x 4
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(p.leftCols(3), Eigen::ComputeThinU | Eigen::ComputeThinV);
  const Eigen::Matrix<double, 2, 3> r2 = svd.matrixU() * svd.matrixV().transpose();
  WeakPerspectivePose pose;
  pose.scale = svd.singularValues().mean();
  pose.rotation.row(0) = r2.row(0);
  pose.rotation.row(1) = r2.row(1);
  pose.rotation.row(2) = r2.row(0).cross(r2.row(1));
  pose.translation = p.col(3);
  return pose;
}

// Gauss-Newton on (omega, s, t) with R <- exp([omega]x) R.
void refine_pose(WeakPerspectivePose& pose, const Eigen::VectorXd& x, const ImageLandmarks& l,
                 const std::vector<int>& use, int iterations) {
  for (int it = 0; it < iterations; ++it) {
    Eigen::Matrix<double, 6, 6> h = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> g = Eigen::Matrix<double, 6, 1>::Zero();
    for (int k : use) {
      const Eigen::Vector3d rx = pose.rotation * x.segment<3>(3 * k);
      const Eigen::Vector2d r =
          pose.scale * rx.head<2>() + pose.translation - l.points[static_cast<std::size_t>(k)];
      Eigen::Matrix<double, 2, 6> j;
      Eigen::Matrix3d skew;
      skew << 0, -rx.z(), rx.y(), rx.z(), 0, -rx.x(), -rx.y(), rx.x(), 0;
      j.leftCols<3>() = -pose.scale * skew.topRows<2>();
      j.col(3) = rx.head<2>();
      j.rightCols<2>().setIdentity();
      h += j.transpose() * j;
      g += j.transpose() * r;
    }
    const Eigen::Matrix<double, 6, 1> step = h.ldlt().solve(-g);
    if (!step.allFinite()) return;
    const Eigen::Vector3d omega = step.head<3>();
    if (omega.norm() > 0)
      pose.rotation =
          Eigen::AngleAxisd(omega.norm(), omega.normalized()).toRotationMatrix() * pose.rotation;
    pose.scale += step[3];
    pose.translation += step.tail<2>();
    if (step.norm() < 1e-10) return;
  }
}

// min |s R2 M w + t - p|^2 + lambda sum (w - mean)^2 / var, M the 204 x K contracted core.
Eigen::VectorXd solve_weights(const std::vector<const Eigen::MatrixXd*>& contracted,
                              const std::vector<const WeakPerspectivePose*>& poses,
                              const std::vector<const ImageLandmarks*>& images,
                              const std::vector<std::vector<int>>& uses, const Prior& prior,
                              double lambda) {
  const Eigen::Index k = contracted.front()->cols();
  Eigen::MatrixXd h = lambda * prior.inverse_variance.asDiagonal();
  Eigen::VectorXd g = lambda * prior.inverse_variance.cwiseProduct(prior.mean);
  for (std::size_t im = 0; im < contracted.size(); ++im) {
    const Eigen::MatrixXd& m = *contracted[im];
    const WeakPerspectivePose& pose = *poses[im];
    const Eigen::Matrix<double, 2, 3> sr = pose.scale * pose.rotation.topRows<2>();
    Eigen::MatrixXd a(2 * static_cast<Eigen::Index>(uses[im].size()), k);
    Eigen::VectorXd b(a.rows());
    for (std::size_t r = 0; r < uses[im].size(); ++r) {
      const int lm = uses[im][r];
      a.middleRows(2 * static_cast<Eigen::Index>(r), 2) = sr * m.middleRows(3 * lm, 3);
      b.segment<2>(2 * static_cast<Eigen::Index>(r)) =
          images[im]->points[static_cast<std::size_t>(lm)] - pose.translation;
    }
    h.noalias() += a.transpose() * a;
    g.noalias() += a.transpose() * b;
  }
  return h.ldlt().solve(g);
}

// The projection is invariant under w -> c w, s -> s / c (the mesh is linear in each weight
// vector), so coordinate descent crawls along that valley; this jumps to the c that minimises
// the prior there, which leaves the data term unchanged and lowers the energy.
double prior_scale(const Eigen::VectorXd& w, const Prior& prior) {
  const double num = w.dot(prior.inverse_variance.cwiseProduct(prior.mean));
  const double den = w.dot(prior.inverse_variance.cwiseProduct(w));
  const double c = den > 0 ? num / den : 1.0;
  return (std::isfinite(c) && c > 1e-3) ? c : 1.0;
}

double mean_error(const Eigen::VectorXd& x, const WeakPerspectivePose& pose,
                  const ImageLandmarks& l, const std::vector<int>& use) {
  double s = 0;
  for (int k : use)
    s += (pose.project(x.segment<3>(3 * k)) - l.points[static_cast<std::size_t>(k)]).norm();
  return use.empty() ? 0.0 : s / static_cast<double>(use.size());
}

std::vector<float> to_floats(const Eigen::VectorXd& v) {
  std::vector<float> out(static_cast<std::size_t>(v.size()));
  for (Eigen::Index i = 0; i < v.size(); ++i)
    out[static_cast<std::size_t>(i)] = static_cast<float>(v[i]);
  return out;
}

struct FitState {
  WeakPerspectivePose pose;
  Eigen::VectorXd w_exp;
  std::vector<int> use;
  bool posed = false;
};

// One image's pose + expression update with the identity fixed.
void update_pose_expression(const Eigen::MatrixXd& core, const BilinearModel& m,
                            const Eigen::VectorXd& w_id, const ImageLandmarks& l,
                            const Prior& exp_prior, const LandmarkFitOptions& o, FitState& s) {
  const Eigen::MatrixXd m_id = by_expression(core, m.id_knobs, m.exp_knobs, s.w_exp);
  const Eigen::VectorXd x = m_id * w_id;
  if (!s.posed) {
    s.pose = affine_pose(x, l, s.use);
    s.posed = true;
  }
  refine_pose(s.pose, x, l, s.use, o.pose_iterations);
  const Eigen::MatrixXd m_exp = by_identity(core, m.id_knobs, m.exp_knobs, w_id);
  s.w_exp = solve_weights({&m_exp}, {&s.pose}, {&l}, {s.use}, exp_prior, o.expression_prior);
  const double c = prior_scale(s.w_exp, exp_prior);
  s.w_exp *= c;
  s.pose.scale /= c;
}

Result<void> check_model(const BilinearModel& m) {
  if (m.id_knobs < 1 || m.exp_knobs < 1 ||
      m.core.size() != static_cast<std::size_t>(m.coordinate_count()) * m.id_knobs * m.exp_knobs ||
      m.identity_factors.size() != static_cast<std::size_t>(m.identity_count) * m.id_knobs ||
      m.expression_factors.size() != static_cast<std::size_t>(m.expression_count) * m.exp_knobs)
    return fail("bilinear model: inconsistent sizes");
  return success();
}

}  // namespace

Result<LandmarkFit> fit_landmarks(const BilinearModel& model, const ImageLandmarks& landmarks,
                                  const LandmarkFitOptions& options) {
  auto joint =
      fit_landmarks_joint(model, std::span<const ImageLandmarks>(&landmarks, 1), options, 0);
  if (!joint) return joint.failure();
  LandmarkFit fit = std::move(joint->images.front());
  fit.w_id = joint->w_id;
  return fit;
}

Result<JointLandmarkFit> fit_landmarks_joint(const BilinearModel& model,
                                             std::span<const ImageLandmarks> images,
                                             const LandmarkFitOptions& options, int rounds) {
  if (auto ok = check_model(model); !ok) return ok.failure();
  if (images.empty()) return fail("landmark fit: no images");
  const Eigen::MatrixXd core = landmark_core(model);
  const Prior id_prior = row_prior(model.identity_factors, model.identity_count, model.id_knobs);
  const Prior exp_prior =
      row_prior(model.expression_factors, model.expression_count, model.exp_knobs);
  Eigen::VectorXd neutral(model.exp_knobs);
  for (int b = 0; b < model.exp_knobs; ++b) neutral[b] = model.expression_row(0)[b];

  std::vector<FitState> states(images.size());
  for (std::size_t i = 0; i < images.size(); ++i) {
    states[i].use = valid_indices(images[i]);
    if (states[i].use.size() < 6)
      return fail("landmark fit: image " + std::to_string(i) + " has " +
                  std::to_string(states[i].use.size()) + " valid landmarks, need at least 6");
    states[i].w_exp = neutral;
  }
  auto identity_step = [&](std::vector<Eigen::VectorXd>& per_image_id, bool shared,
                           Eigen::VectorXd& w_shared) {
    std::vector<Eigen::MatrixXd> contracted(images.size());
    for (std::size_t i = 0; i < images.size(); ++i)
      contracted[i] = by_expression(core, model.id_knobs, model.exp_knobs, states[i].w_exp);
    if (shared) {
      std::vector<const Eigen::MatrixXd*> ms;
      std::vector<const WeakPerspectivePose*> ps;
      std::vector<const ImageLandmarks*> ls;
      std::vector<std::vector<int>> us;
      for (std::size_t i = 0; i < images.size(); ++i) {
        ms.push_back(&contracted[i]);
        ps.push_back(&states[i].pose);
        ls.push_back(&images[i]);
        us.push_back(states[i].use);
      }
      w_shared = solve_weights(ms, ps, ls, us, id_prior, options.identity_prior);
      const double c = prior_scale(w_shared, id_prior);
      w_shared *= c;
      for (auto& st : states) st.pose.scale /= c;
    } else {
      for (std::size_t i = 0; i < images.size(); ++i) {
        per_image_id[i] = solve_weights({&contracted[i]}, {&states[i].pose}, {&images[i]},
                                        {states[i].use}, id_prior, options.identity_prior);
        const double c = prior_scale(per_image_id[i], id_prior);
        per_image_id[i] *= c;
        states[i].pose.scale /= c;
      }
    }
  };
  auto errors = [&](const std::vector<Eigen::VectorXd>& ids) {
    std::vector<double> e(images.size());
    for (std::size_t i = 0; i < images.size(); ++i) {
      const Eigen::VectorXd x =
          by_expression(core, model.id_knobs, model.exp_knobs, states[i].w_exp) * ids[i];
      e[i] = mean_error(x, states[i].pose, images[i], states[i].use);
    }
    return e;
  };

  // Independent fits (section 4.1.2), all images at once.
  std::vector<Eigen::VectorXd> ids(images.size(), id_prior.mean);
  std::vector<std::vector<double>> history(images.size());
  Eigen::VectorXd unused;
  for (int it = 0; it < std::max(1, options.iterations); ++it) {
    for (std::size_t i = 0; i < images.size(); ++i) {
      const Eigen::MatrixXd m_id =
          by_expression(core, model.id_knobs, model.exp_knobs, states[i].w_exp);
      const Eigen::VectorXd x = m_id * ids[i];
      if (!states[i].posed) {
        states[i].pose = affine_pose(x, images[i], states[i].use);
        states[i].posed = true;
      }
      refine_pose(states[i].pose, x, images[i], states[i].use, options.pose_iterations);
    }
    identity_step(ids, false, unused);
    for (std::size_t i = 0; i < images.size(); ++i) {
      const Eigen::MatrixXd m_exp = by_identity(core, model.id_knobs, model.exp_knobs, ids[i]);
      states[i].w_exp = solve_weights({&m_exp}, {&states[i].pose}, {&images[i]}, {states[i].use},
                                      exp_prior, options.expression_prior);
      const double c = prior_scale(states[i].w_exp, exp_prior);
      states[i].w_exp *= c;
      states[i].pose.scale /= c;
    }
    const auto e = errors(ids);
    for (std::size_t i = 0; i < images.size(); ++i) history[i].push_back(e[i]);
  }

  // Joint rounds (eq. 15): shared identity, then each image's pose and expression.
  Eigen::VectorXd w_id = ids.front();
  if (images.size() > 1 || rounds > 0) {
    for (int r = 0; r < rounds; ++r) {
      identity_step(ids, true, w_id);
      for (int inner = 0; inner < 3; ++inner)
        for (std::size_t i = 0; i < images.size(); ++i)
          update_pose_expression(core, model, w_id, images[i], exp_prior, options, states[i]);
      std::fill(ids.begin(), ids.end(), w_id);
      const auto e = errors(ids);
      for (std::size_t i = 0; i < images.size(); ++i) history[i].push_back(e[i]);
    }
  }
  JointLandmarkFit out;
  out.w_id = to_floats(rounds > 0 ? w_id : ids.front());
  double sum = 0;
  for (std::size_t i = 0; i < images.size(); ++i) {
    LandmarkFit f;
    f.pose = states[i].pose;
    f.w_id = to_floats(ids[i]);
    f.w_exp = to_floats(states[i].w_exp);
    f.error_history_px = history[i];
    f.mean_error_px = history[i].back();
    sum += f.mean_error_px;
    out.images.push_back(std::move(f));
  }
  out.mean_error_px = sum / static_cast<double>(images.size());
  return out;
}

std::vector<std::vector<float>> image_blendshapes(const BilinearModel& model,
                                                  std::span<const float> w_id) {
  std::vector<std::vector<float>> out;
  out.reserve(static_cast<std::size_t>(model.expression_count));
  for (int e = 0; e < model.expression_count; ++e) {
    std::vector<float> mesh(static_cast<std::size_t>(model.coordinate_count()));
    model.evaluate(w_id, model.expression_row(e), mesh);
    out.push_back(std::move(mesh));
  }
  return out;
}

std::vector<AttributeDefinition> default_attributes() {
  return {{"face_length", 27, 8}, {"face_width", 0, 16},   {"mouth_width", 48, 54},
          {"nose_width", 31, 35}, {"nose_length", 27, 33}, {"eye_distance", 39, 42}};
}

std::vector<double> measure_attributes(std::span<const float> mesh,
                                       const std::array<std::uint32_t, 68>& lv,
                                       std::span<const AttributeDefinition> attributes) {
  std::vector<double> out;
  for (const auto& a : attributes) {
    const std::uint32_t i = lv[static_cast<std::size_t>(a.landmark_a)];
    const std::uint32_t j = lv[static_cast<std::size_t>(a.landmark_b)];
    const Eigen::Vector3d p(mesh[3 * i], mesh[3 * i + 1], mesh[3 * i + 2]);
    const Eigen::Vector3d q(mesh[3 * j], mesh[3 * j + 1], mesh[3 * j + 2]);
    out.push_back((p - q).norm());
  }
  return out;
}

Result<AttributeRegression> fit_attribute_regression(
    const BilinearModel& model, std::span<const AttributeDefinition> attributes) {
  if (auto ok = check_model(model); !ok) return ok.failure();
  const int l = static_cast<int>(attributes.size());
  for (const auto& a : attributes)
    if (a.landmark_a < 0 || a.landmark_a >= 68 || a.landmark_b < 0 || a.landmark_b >= 68)
      return fail("attribute '" + a.name + "': landmark indices must be 0..67");
  if (model.identity_count <= l + 1)
    return fail("attribute regression needs more training identities (" +
                std::to_string(model.identity_count) + ") than attributes + 1 (" +
                std::to_string(l + 1) + ")");
  Eigen::MatrixXd w(model.id_knobs, model.identity_count);
  Eigen::MatrixXd f(l + 1, model.identity_count);
  std::vector<float> mesh(static_cast<std::size_t>(model.coordinate_count()));
  for (int i = 0; i < model.identity_count; ++i) {
    const auto row = model.identity_row(i);
    for (int a = 0; a < model.id_knobs; ++a) w(a, i) = row[a];
    model.evaluate(row, model.expression_row(0), mesh);
    const auto values = measure_attributes(mesh, model.landmark_vertices, attributes);
    for (int k = 0; k < l; ++k) f(k, i) = values[static_cast<std::size_t>(k)];
    f(l, i) = 1.0;
  }
  // M = W F^T (F F^T)^-1 (eq. 12), solved rather than inverted.
  const Eigen::MatrixXd fft = f * f.transpose();
  AttributeRegression out;
  out.attributes.assign(attributes.begin(), attributes.end());
  out.mapping = fft.ldlt().solve(f * w.transpose()).transpose();
  if (!out.mapping.allFinite())
    return fail(
        "attribute regression: the attributes are linearly dependent over the training set");
  return out;
}

std::vector<float> apply_attribute_change(const AttributeRegression& regression,
                                          std::span<const float> w_id,
                                          std::span<const double> change) {
  Eigen::VectorXd df = Eigen::VectorXd::Zero(regression.mapping.cols());
  for (std::size_t k = 0; k < change.size() && k + 1 < static_cast<std::size_t>(df.size()); ++k)
    df[static_cast<Eigen::Index>(k)] = change[k];
  const Eigen::VectorXd dw = regression.mapping * df;
  std::vector<float> out(w_id.begin(), w_id.end());
  for (std::size_t a = 0; a < out.size() && a < static_cast<std::size_t>(dw.size()); ++a)
    out[a] += static_cast<float>(dw[static_cast<Eigen::Index>(a)]);
  return out;
}

}  // namespace fb
