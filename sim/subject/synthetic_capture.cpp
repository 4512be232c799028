#include "sim/subject/synthetic_capture.hpp"

#include <chrono>

#include "algo/core/clock.hpp"
#include "algo/fusion/view_consistency.hpp"
#include "algo/landmarks/face_region_box.hpp"
#include "algo/landmarks/landmark_lifting.hpp"
#include "algo/landmarks/skin_map.hpp"
#include "sim/camera/synthetic_camera.hpp"
#include "sim/camera/world_presets.hpp"
#include "storage/asset_files.hpp"

namespace fb::cli {

Result<Capture> capture(const FaceModel& model, const std::vector<float>& identity,
                        const std::vector<float>& weights, std::uint64_t seed, int frames,
                        bool keep_colors, std::span<const float> personal_expression_basis,
                        std::string_view world, std::uint64_t world_seed, UnitCalibration unit,
                        LandmarkDetector* face_detector, bool keep_frames) {
  SyntheticOptions so;
  so.personal_expression_basis.assign(personal_expression_basis.begin(),
                                      personal_expression_basis.end());
  so.seed = seed;
  so.identity_coeffs = identity;
  so.expression_weights = weights;
  so.frame_count = frames;
  if (!world.empty())
    if (auto ok = apply_world_preset(world, world_seed, so); !ok) return ok.failure();
  auto calibration = unit_calibration_for(model, so, unit);
  if (!calibration) return calibration.failure();
  auto camera = make_synthetic_camera(model, so);
  if (!camera) return camera.failure();
  if (auto ok = (*camera)->start(); !ok) return ok.failure();
  Capture c;
  c.intrinsics = (*camera)->info().depth_intrinsics;
  c.calibration = *calibration;
  FaceFusion fusion;
  ViewConsistency consistency;
  if (auto ok = consistency.reset(c.intrinsics); !ok) return ok.failure();
  RgbdFrame frame;
  RigidPose first;
  bool started = false;
  const auto t0 = Clock::now();
  for (int i = 0; i < frames; ++i) {
    auto st = (*camera)->next_frame(frame, std::chrono::milliseconds(1000));
    if (!st) return st.failure();
    if (*st != FrameStatus::kFrame) break;
    if (i == 0) {
      // The face box: where dlib finds the face on this frame (the registration the capture
      // believes in maps it into the depth image), else the kiosk's fixed rectangle.
      c.box = default_face_box(c.intrinsics.width, c.intrinsics.height);
      c.box_source = "fixed";
      if (!face_detector) {
        c.box_note = "no face detector";
      } else {
        auto region =
            detect_face_region(*face_detector, frame.color, frame.depth_mm,
                               KinectRegistration(c.calibration), face_proportions(model));
        if (region) {
          c.box = region->box;
          c.box_source = "dlib";
        } else {
          c.box_note = region.error().message;
        }
      }
      if (auto ok = fusion.reset(c.intrinsics, c.box); !ok) return ok.failure();
    }
    const FrameReport r = fusion.process(frame.depth_mm);
    c.fused_frames += r.fused;
    c.dropped_frames += r.state == TrackingState::kLost;
    if (i == 0) {
      const FrameTruth* t = frame_truth(**camera);
      if (!t) return fail("the synthetic camera gave no ground truth");
      c.color = frame.color;
      c.truth_color_px = t->landmarks_color_px;
      c.truth_depth_px = t->landmarks_depth_px;
      c.noiseless = t->noiseless_depth_mm;
      c.truth_pose = t->camera_from_model;
      // The rendered skin itself (it holds a personal expression basis when one is given).
      c.truth_mesh.resize(static_cast<std::size_t>(model.vertex_count) * 3);
      const auto rendered = (*camera)->model_vertices();
      for (int v = 0; v < model.vertex_count; ++v)
        for (int a = 0; a < 3; ++a) c.truth_mesh[3 * v + a] = rendered[v][a];
      if (r.state != TrackingState::kStarted)
        return fail(
            std::string(
                "fusion did not start on the frontal frame (too little face depth in the ") +
            (c.box_source == "dlib" ? "detected" : "fixed") + " face box)");
      first = r.world_from_camera;
      started = true;
    }
    if (r.fused)
      consistency.add(frame.depth_mm, fusion.model_view().levels[0].depth,
                      relative_pose(first, r.world_from_camera), fusion.face_box().rect);
    if (keep_colors) c.colors.push_back(frame.color);
    if (keep_frames) c.frames.push_back(frame);
  }
  if (keep_frames) c.camera = std::shared_ptr<const SyntheticCamera>(std::move(*camera));
  if (!started) return fail("no frames");
  c.fusion_ms = ms_since(t0);
  c.fused = fusion.render(first);
  consistency.confidence(c.confidence);
  return c;
}

RigidPose fitted_to_truth(const Capture& c, const RigidPose& fitted_camera_from_model) {
  // Both poses map into the camera frame: the fitted model frame seen from the true one.
  return relative_pose(c.truth_pose, fitted_camera_from_model);
}

Result<FitTarget> make_fit_target(const Capture& c, std::span<const Eigen::Vector2d> color_px,
                                  bool noiseless_depth, bool skin) {
  const KinectRegistration registration(c.calibration);
  const Image<float>& depth = noiseless_depth ? c.noiseless : c.fused.depth_mm;
  auto lifted = lift_landmarks(color_px, depth, registration);
  if (!lifted) return lifted.failure();
  FitTarget t;
  t.intrinsics = c.intrinsics;
  t.depth_mm = depth;
  if (!noiseless_depth) {
    t.normals = c.fused.normals;
    t.confidence = c.confidence;
  }
  t.landmarks = *lifted;
  // Where the fused depth sees skin, from frame 0's colour (the product does the same).
  if (skin && !noiseless_depth)
    if (auto map = skin_map(depth, c.color, registration, color_px)) t.skin = std::move(*map);
  if (auto ok = prepare_fit_target(t); !ok) return ok.failure();
  return t;
}

std::vector<Eigen::Vector2d> noisy(const std::vector<Eigen::Vector2d>& px, double sigma,
                                   std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, sigma);
  std::vector<Eigen::Vector2d> out = px;
  if (sigma > 0)
    for (auto& p : out) p += Eigen::Vector2d(n(rng), n(rng));
  return out;
}

}  // namespace fb::cli
