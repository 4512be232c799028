#include "host/cli/session_refit.hpp"

#include <cmath>
#include <map>
#include <optional>

#include "algo/core/clock.hpp"
#include "algo/fitting/expression_transfer.hpp"
#include "algo/fitting/fit_qa.hpp"
#include "algo/landmarks/landmark_lifting.hpp"
#include "algo/landmarks/skin_map.hpp"
#include "host/cli/session_texture.hpp"  // session_calibration

namespace fb::cli {

RefitOptions full_fit_options() {
  RefitOptions o;
  // More of the PCA step than the booth affords (booth: 7 rounds, every 2nd fitting vertex in
  // the depth term). More refinement steps (30 instead of 12) made it worse: docs/sync.md.
  o.neutral.rounds = 12;
  o.neutral.depth_vertex_stride = 1;
  return o;
}

namespace {

// A capture's fit target from what the store keeps: the fused depth (whole mm) and the colour
// landmarks lifted into it through the unit's registration, as the booth lifted them.
Result<FitTarget> stored_target(const SessionStore& store, SessionId session, int index,
                                const KinectCalibration& calibration,
                                const std::optional<LandmarkEmbedding>& embedding) {
  CaptureReadOptions ro;
  ro.max_frames = 1;  // frame 0's colour: where the fused depth sees skin
  auto c = store.read_capture(session, index, ro);
  if (!c) return c.failure();
  if (c->fused_depth.width == 0) return fail("no fused depth stored");
  if (c->landmarks.size() != 68) return fail("no landmarks stored");
  std::array<Eigen::Vector2d, 68> px;
  for (int i = 0; i < 68; ++i)
    px[static_cast<std::size_t>(i)] = Eigen::Vector2d(c->landmarks[static_cast<std::size_t>(i)].u,
                                                      c->landmarks[static_cast<std::size_t>(i)].v);
  FitTarget t;
  t.intrinsics = calibration.depth_intrinsics();
  t.depth_mm = depth_to_float(c->fused_depth);
  const KinectRegistration registration(calibration);
  auto lifted = lift_landmarks(px, t.depth_mm, registration);
  if (!lifted) return lifted.failure();
  t.landmarks = *lifted;
  if (!c->frames.empty())
    if (auto skin = skin_map(t.depth_mm, c->frames.front().color, registration, px))
      t.skin = std::move(*skin);
  if (embedding) t.landmark_vertices = embedding->for_expression(c->info.expression);
  if (auto ok = prepare_fit_target(t); !ok) return ok.failure();
  return t;
}

// The newest fitted mesh of each capture (what `rig` would use).
Result<std::map<int, MeshId>> newest_meshes(const SessionStore& store, SessionId session) {
  auto meshes = store.meshes(session);
  if (!meshes) return meshes.failure();
  std::map<int, MeshId> out;
  for (const auto& m : *meshes)
    if (m.capture_index && m.role != MeshRole::kScan)
      out[*m.capture_index] = std::max(out[*m.capture_index], m.id);
  return out;
}

}  // namespace

Result<RefitReport> refit_session(SessionStore& store, SessionId session, const FaceModel& model,
                                  const GuideSet& guide, const RefitOptions& options) {
  const auto t0 = Clock::now();
  auto info = store.session(session);
  if (!info) return info.failure();
  RefitReport report;
  auto calibration = session_calibration(*info, report.calibration_note);
  if (!calibration) return calibration.failure();
  auto captures = store.captures(session);
  if (!captures) return captures.failure();
  auto previous = newest_meshes(store, session);
  if (!previous) return previous.failure();
  const std::string where = "session " + std::to_string(session);
  std::vector<const CaptureInfo*> done;
  for (const auto& c : *captures)
    if (c.state == CaptureState::kDone) done.push_back(&c);
  if (done.empty() || done.front()->index != 0)
    return fail(where + " has no done neutral capture (capture 0); the refit starts from it");

  std::optional<ExpressionTransfer> transfer;
  std::vector<float> g0;
  RigidPose neutral_pose;
  std::vector<MeshInput> meshes;
  int finished = 0;
  for (const CaptureInfo* c : done) {
    const std::string label = c->expression + " (capture " + std::to_string(c->index) + ")";
    const int g = guide.find(c->expression);
    auto target = stored_target(store, session, c->index, *calibration, options.embedding);
    if (g < 0 || !target) {
      const std::string why =
          g < 0 ? "'" + c->expression + "' is not a guide recipe" : target.error().message;
      if (c->index == 0) return fail(where + ": cannot refit the neutral: " + why);
      report.skipped.push_back(label + ": " + why);
      continue;
    }
    auto gm = guide_mesh(guide.expressions[static_cast<std::size_t>(g)], model);
    if (!gm) return gm.failure();
    auto parts = guide_part_meshes(guide.expressions[static_cast<std::size_t>(g)], model);
    if (!parts) return parts.failure();
    const auto tf = Clock::now();
    Result<FitResult> fit = c->index == 0
                                ? fit_neutral(model, *target, options.neutral)
                                : fit_expression(model, *transfer, *gm, *target, options.expression,
                                                 neutral_pose, *parts);
    if (!fit) {
      if (c->index == 0) return fail(where + ": the neutral refit failed: " + fit.error().message);
      report.skipped.push_back(label + ": " + fit.error().message);
      continue;
    }
    if (c->index == 0) {
      g0 = *gm;
      neutral_pose = fit->camera_from_model;
      auto t =
          ExpressionTransfer::create(model, fit->vertices, g0, options.expression.refine_options);
      if (!t)
        return fail(where + ": expression transfer from the refit neutral: " + t.error().message);
      transfer.emplace(std::move(*t));
    }
    RefitCapture rc;
    rc.index = c->index;
    rc.expression = c->expression;
    rc.previous_mesh = previous->count(c->index) ? previous->at(c->index) : 0;
    rc.rms_to_depth_mm = fit->rms_to_depth_mm;
    rc.landmark_error_mm = landmark_disagreement_mm(*fit, *target);
    rc.fit_ms = ms_since(tf);
    report.captures.push_back(rc);
    meshes.push_back(MeshInput{c->index, c->index == 0 ? MeshRole::kNeutral : MeshRole::kFitted,
                               c->expression, MeshData{std::move(fit->vertices), model.triangles}});
    if (options.progress) options.progress(++finished, static_cast<int>(done.size()));
  }
  auto ids = store.add_meshes(session, meshes);
  if (!ids) return fail(where + ": storing the refit meshes: " + ids.error().message);
  for (std::size_t k = 0; k < ids->size(); ++k) report.captures[k].mesh = (*ids)[k];
  report.seconds = seconds_since(t0);
  return report;
}

}  // namespace fb::cli
