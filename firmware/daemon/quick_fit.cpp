#include "firmware/daemon/quick_fit.hpp"
#include "algo/core/clock.hpp"

#include <chrono>
#include <cmath>
#include <fstream>

#include <Eigen/Cholesky>
#include <Eigen/Dense>

#include "algo/fitting/expression_transfer.hpp"
#include "algo/fitting/fit_qa.hpp"
#include "algo/guide/guide_expressions.hpp"
#include "algo/landmarks/landmark_detector.hpp"
#include "algo/landmarks/landmark_lifting.hpp"
#include "algo/landmarks/skin_map.hpp"
#include "storage/asset_files.hpp"

namespace fb {

struct QuickFitter::State {
  FaceModel model;
  std::optional<LandmarkDetector> detector;
  // dlib's landmark convention on the model (beside the model file); unset = the model's own.
  std::optional<LandmarkEmbedding> embedding;
  std::vector<std::vector<float>> guide_meshes;  // G_i, model frame
  // Per guide expression: G0 plus each part of its recipe (the expression fit's parts).
  std::vector<std::vector<std::vector<float>>> guide_parts;
  std::vector<std::string> guide_names;
  double load_ms = 0;

  std::int64_t neutral_session = 0;
  std::vector<float> neutral;  // S0, model frame
  std::optional<RigidPose> neutral_pose;
  std::vector<float> identity;
  std::optional<ExpressionTransfer> transfer;  // G0 -> Gi onto S0

  Result<void> set_neutral(std::int64_t session, std::span<const float> mesh,
                           const std::optional<RigidPose>& pose,
                           std::vector<float> identity_coeffs) {
    auto t = ExpressionTransfer::create(model, mesh, guide_meshes.front());
    if (!t) return fail("expression transfer from the fitted neutral: " + t.error().message);
    transfer.emplace(std::move(*t));
    neutral.assign(mesh.begin(), mesh.end());
    neutral_pose = pose;
    identity = std::move(identity_coeffs);
    neutral_session = session;
    return success();
  }

  // The transfer an expression fit of `session` starts from: the session's neutral, or, when it
  // has none (it failed, or the store has none), the mean face, which still gives the
  // refinement a start in the right expression. True when the mean face stands in.
  Result<bool> transfer_for(std::int64_t session) {
    if (neutral_session == session && transfer) return false;
    if (auto ok = set_neutral(0, guide_meshes.front(), std::nullopt, {}); !ok) return ok.failure();
    return true;
  }
};

namespace {

// The target of one capture: its fused depth and the 68 colour points lifted into it.
Result<FitTarget> make_target(const CaptureView& view,
                              const std::array<Eigen::Vector2d, 68>& color_points,
                              const std::optional<LandmarkEmbedding>& embedding,
                              std::string_view expression, QuickFitResult& out) {
  const KinectRegistration registration(view.calibration);
  auto lifted = lift_landmarks(color_points, view.depth_mm, registration);
  if (!lifted) return lifted.failure();
  FitTarget target;
  target.intrinsics = view.intrinsics;
  target.depth_mm = view.depth_mm;
  target.normals = view.normals;
  target.confidence = view.confidence;
  target.landmarks = *lifted;
  // Without a skin map (no colour frame) every depth sample counts as skin.
  if (auto skin = skin_map(view.depth_mm, view.color, registration, color_points))
    target.skin = std::move(*skin);
  if (embedding) target.landmark_vertices = embedding->for_expression(expression);
  out.landmarks_valid = 0;
  out.landmarks_3d = 0;
  for (const auto& l : target.landmarks) {
    out.landmarks_valid += l.valid;
    out.landmarks_3d += l.valid && l.point.has_value();
  }
  if (auto ok = prepare_fit_target(target); !ok) return ok.failure();
  return target;
}

}  // namespace

std::vector<Landmark> QuickFitResult::stored_landmarks(const PinholeIntrinsics&) const {
  std::vector<Landmark> out(68);
  for (int i = 0; i < 68; ++i) {
    Landmark& l = out[static_cast<std::size_t>(i)];
    l.u = static_cast<float>(color_points[static_cast<std::size_t>(i)].x());
    l.v = static_cast<float>(color_points[static_cast<std::size_t>(i)].y());
    const FitLandmark& f = target.landmarks[static_cast<std::size_t>(i)];
    if (f.valid && f.point) {
      l.has_3d = true;
      l.x = static_cast<float>(f.point->x());
      l.y = static_cast<float>(f.point->y());
      l.z = static_cast<float>(f.point->z());
    }
  }
  return out;
}

QuickFitter::QuickFitter(std::unique_ptr<State> state) : state_(std::move(state)) {}
QuickFitter::~QuickFitter() = default;

Result<std::unique_ptr<QuickFitter>> QuickFitter::create(const QuickFitPaths& paths,
                                                         const std::vector<GuideStep>& guide) {
  auto state = std::make_unique<State>();
  auto model = load_face_model(paths.face_model);
  if (!model)
    return fail("cannot load the face model '" + paths.face_model.string() +
                "': " + model.error().message + " (set [session] face_model)");
  state->model = std::move(*model);
  auto embedding = landmark_embedding_beside(state->model, paths.face_model);
  if (!embedding) return fail("dlib's landmark embedding: " + embedding.error().message);
  state->embedding = *embedding;
  if (guide.empty()) return fail("the guide has no expressions");
  for (std::size_t i = 0; i < guide.size(); ++i) {
    GuideExpression g;
    g.id = static_cast<int>(i);
    g.name = guide[i].name;
    g.weights = guide[i].weights;
    auto mesh = guide_mesh(g, state->model);
    if (!mesh) return fail("guide expression '" + g.name + "': " + mesh.error().message);
    auto parts = guide_part_meshes(g, state->model);
    if (!parts) return fail("guide expression '" + g.name + "': " + parts.error().message);
    state->guide_meshes.push_back(std::move(*mesh));
    state->guide_parts.push_back(std::move(*parts));
    state->guide_names.push_back(g.name);
  }
  const auto t0 = std::chrono::steady_clock::now();
  std::ifstream in(paths.shape_predictor, std::ios::binary);
  if (!in)
    return fail("cannot read the landmark model '" + paths.shape_predictor.string() +
                "' (install Debian's libdlib-data or set [session] shape_predictor)");
  auto detector = LandmarkDetector::create(in);
  if (!detector)
    return fail("landmark model '" + paths.shape_predictor.string() +
                "': " + detector.error().message);
  state->detector.emplace(std::move(*detector));
  state->load_ms = ms_since(t0);
  return std::unique_ptr<QuickFitter>(new QuickFitter(std::move(state)));
}

const FaceModel& QuickFitter::model() const {
  return state_->model;
}
std::int64_t QuickFitter::neutral_session() const {
  return state_->neutral_session;
}
const std::vector<float>& QuickFitter::identity() const {
  return state_->identity;
}
double QuickFitter::landmark_model_load_ms() const {
  return state_->load_ms;
}
LandmarkDetector QuickFitter::share_landmark_detector() const {
  return state_->detector->share();
}
void QuickFitter::forget_neutral() {
  state_->neutral_session = 0;
  state_->transfer.reset();
  state_->neutral.clear();
  state_->neutral_pose.reset();
  state_->identity.clear();
}

Result<void> QuickFitter::set_neutral(std::int64_t session, std::span<const float> neutral_mesh) {
  if (neutral_mesh.size() != state_->model.neutral.size())
    return fail("the stored neutral mesh does not have the face model's vertex count");
  return state_->set_neutral(session, neutral_mesh, std::nullopt,
                             project_identity(state_->model, neutral_mesh));
}

Result<QuickFitResult> QuickFitter::fit(std::int64_t session, int guide_index,
                                        const CaptureView& view) {
  state_->detector->reset_tracking();  // one frame per capture: a full-image detection
  auto found = state_->detector->detect(view.color);
  if (!found) return found.failure();
  return fit_with_points(session, guide_index, view, found->points, found->detection_score);
}

Result<QuickFitResult> QuickFitter::fit_with_points(
    std::int64_t session, int guide_index, const CaptureView& view,
    const std::array<Eigen::Vector2d, 68>& color_points, double detection_score) {
  State& s = *state_;
  if (guide_index < 0 || guide_index >= static_cast<int>(s.guide_meshes.size()))
    return fail("capture " + std::to_string(guide_index) + " is not in the guide");
  QuickFitResult r;
  r.color_points = color_points;
  r.detection_score = detection_score;
  auto target = make_target(view, r.color_points, state_->embedding,
                            s.guide_names[static_cast<std::size_t>(guide_index)], r);
  if (!target) return target.failure();
  r.target = std::move(*target);
  if (guide_index == 0) {
    auto fit = fit_neutral(s.model, r.target);
    if (!fit) return fit.failure();
    r.fit = std::move(*fit);
    r.neutral = true;
    if (auto ok =
            s.set_neutral(session, r.fit.vertices, r.fit.camera_from_model, r.fit.identity_coeffs);
        !ok)
      return ok.failure();
  } else {
    auto mean_face = s.transfer_for(session);
    if (!mean_face) return mean_face.failure();
    if (*mean_face) r.neutral_was_mean_face = true;
    std::optional<RigidPose> seed;
    if (s.neutral_session == session) seed = s.neutral_pose;  // nullopt for a stored neutral
    auto fit =
        fit_expression(s.model, *s.transfer, s.guide_meshes[static_cast<std::size_t>(guide_index)],
                       r.target, {}, seed, s.guide_parts[static_cast<std::size_t>(guide_index)]);
    if (!fit) return fit.failure();
    r.fit = std::move(*fit);
  }
  r.landmark_error_mm = landmark_disagreement_mm(r.fit, r.target);
  return r;
}

Result<void> QuickFitter::refit(std::int64_t session, int guide_index, const CaptureView& view,
                                std::span<const ColorCorrection> corrections,
                                QuickFitResult& result) {
  State& s = *state_;
  if (guide_index < 0 || guide_index >= static_cast<int>(s.guide_meshes.size()))
    return fail("capture " + std::to_string(guide_index) + " is not in the guide");
  QuickFitResult next = result;
  for (const auto& c : corrections) {
    if (c.index < 0 || c.index >= 68)
      return fail("landmark index " + std::to_string(c.index) + " is not in 0..67");
    if (!(c.u >= 0 && c.v >= 0 && c.u < view.color.width && c.v < view.color.height))
      return fail("landmark " + std::to_string(c.index) + " moved outside the colour image");
    next.color_points[static_cast<std::size_t>(c.index)] = Eigen::Vector2d(c.u, c.v);
    next.corrected[static_cast<std::size_t>(c.index)] = true;
  }
  auto target = make_target(view, next.color_points, state_->embedding,
                            s.guide_names[static_cast<std::size_t>(guide_index)], next);
  if (!target) return target.failure();
  next.target = std::move(*target);
  if (guide_index == 0) {
    auto fit = fit_neutral(s.model, next.target, {}, &result.fit);
    if (!fit) return fit.failure();
    next.fit = std::move(*fit);
    if (auto ok = s.set_neutral(session, next.fit.vertices, next.fit.camera_from_model,
                                next.fit.identity_coeffs);
        !ok)
      return ok.failure();
  } else {
    if (auto mean_face = s.transfer_for(session); !mean_face) return mean_face.failure();
    auto fit = fit_expression(
        s.model, *s.transfer, s.guide_meshes[static_cast<std::size_t>(guide_index)], next.target,
        {}, result.fit.camera_from_model, s.guide_parts[static_cast<std::size_t>(guide_index)]);
    if (!fit) return fit.failure();
    next.fit = std::move(*fit);
  }
  next.landmark_error_mm = landmark_disagreement_mm(next.fit, next.target);
  result = std::move(next);
  return success();
}

MeshData QuickFitter::mesh(const QuickFitResult& result) const {
  return MeshData{result.fit.vertices, state_->model.triangles};
}

std::vector<float> project_identity(const FaceModel& model, std::span<const float> neutral_mesh,
                                    int modes, double lambda) {
  const int k = std::min(modes, model.identity_count);
  const int n = 3 * model.face_vertex_count;
  if (k <= 0 || static_cast<int>(neutral_mesh.size()) < n) return {};
  // Normal equations straight from the model's basis (no n x k copy: ~11 MB saved).
  Eigen::MatrixXd normal(k, k);
  Eigen::VectorXd rhs(k);
  Eigen::Map<const Eigen::VectorXf> mesh(neutral_mesh.data(), n);
  Eigen::Map<const Eigen::VectorXf> mean(model.neutral.data(), n);
  const Eigen::VectorXf d = mesh - mean;
  for (int j = 0; j < k; ++j) {
    Eigen::Map<const Eigen::VectorXf> bj(model.identity_mode(j).data(), n);
    rhs[j] = bj.cast<double>().dot(d.cast<double>());
    for (int l = 0; l <= j; ++l) {
      Eigen::Map<const Eigen::VectorXf> bl(model.identity_mode(l).data(), n);
      normal(j, l) = normal(l, j) = bj.cast<double>().dot(bl.cast<double>());
    }
  }
  normal.diagonal().array() += lambda;
  const Eigen::VectorXd c = normal.ldlt().solve(rhs);
  std::vector<float> out(static_cast<std::size_t>(k));
  for (int j = 0; j < k; ++j) out[static_cast<std::size_t>(j)] = static_cast<float>(c[j]);
  return out;
}

}  // namespace fb
