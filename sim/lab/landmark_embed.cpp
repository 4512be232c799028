// `facebooth-lab landmarks embed`: learns dlib's landmark convention on the face model
// (algo/facemodel/landmark_embedding.hpp) from textured synthetic renders of subjects the
// evaluations do not use (seeds from 1000), several expressions and head poses each: every
// dlib point is mapped into the depth image through the true registration and given the
// visible mesh vertex that projects nearest to it.
#include <iostream>

#include "algo/facemodel/landmark_embedding.hpp"
#include "algo/guide/guide_expressions.hpp"
#include "algo/landmarks/landmark_lifting.hpp"
#include "host/cli/guide_files.hpp"
#include "host/cli/progress.hpp"
#include "host/cli/tracker_setup.hpp"
#include "sim/camera/frame_truth.hpp"
#include "sim/camera/synthetic_camera.hpp"
#include "sim/camera/world_presets.hpp"
#include "sim/lab/lab_commands.hpp"
#include "storage/asset_files.hpp"
#include "storage/durable_file.hpp"

namespace fb::cli {
int report_failure(const Error& error);

namespace {

// The visible face vertex whose projection is nearest to `px` (depth image), or -1.
int nearest_visible_vertex(const FrameTruth& truth, std::span<const Eigen::Vector3f> mesh,
                           int face_vertices, const PinholeIntrinsics& k,
                           const Eigen::Vector2d& px) {
  int best = -1;
  double best_d = 4.0 * 4.0;  // px: farther than this, dlib's point is off the face
  for (int v = 0; v < face_vertices; ++v) {
    const Eigen::Vector3d p =
        truth.camera_from_model.apply(mesh[static_cast<std::size_t>(v)].cast<double>());
    const Eigen::Vector2d q = k.project(p);
    const double d = (q - px).squaredNorm();
    if (d >= best_d) continue;
    const int x = static_cast<int>(std::lround(q.x())), y = static_cast<int>(std::lround(q.y()));
    if (x < 0 || y < 0 || x >= truth.noiseless_depth_mm.width ||
        y >= truth.noiseless_depth_mm.height)
      continue;
    const float z = truth.noiseless_depth_mm.at(x, y);
    if (!(z > 0.0f) || std::abs(z - p.z()) > 4.0) continue;  // hidden behind another surface
    best_d = d;
    best = v;
  }
  return best;
}

struct EmbedRun {
  std::map<std::string, LandmarkHits> hits;  // by guide expression
  int renders = 0, detected = 0;
};

Result<void> embed_subject(const FaceModel& model, const GuideSet& guide,
                           LandmarkDetector& detector, std::uint64_t seed, int frames, int views,
                           const std::string& world, EmbedRun& run) {
  for (std::size_t e = 0; e < guide.expressions.size(); ++e) {
    auto weights = guide_weights(guide.expressions[e], model);
    if (!weights) return weights.failure();
    SyntheticOptions so;
    so.seed = seed * 100 + e;
    so.identity_coeffs = identity_draw(seed, model.identity_count);
    so.expression_weights = *weights;
    so.frame_count = frames;
    if (auto ok = apply_world_preset(world, seed, so); !ok) return ok.failure();
    auto camera = make_synthetic_camera(model, so);
    if (!camera) return camera.failure();
    if (auto ok = (*camera)->start(); !ok) return ok.failure();
    const KinectRegistration registration(so.calibration);
    const PinholeIntrinsics k = (*camera)->info().depth_intrinsics;
    LandmarkHits& hits = run.hits[guide.expressions[e].name];
    RgbdFrame frame;
    for (int i = 0; i < frames; ++i) {
      auto st = (*camera)->next_frame(frame, std::chrono::milliseconds(1000));
      if (!st) return st.failure();
      if (*st != FrameStatus::kFrame) break;
      if (i % std::max(1, frames / views) != 0) continue;
      const FrameTruth* truth = frame_truth(**camera);
      if (!truth || truth->noiseless_depth_mm.empty())
        return fail("the synthetic camera gave no ground truth");
      ++run.renders;
      detector.reset_tracking();
      auto found = detector.detect(frame.color);
      if (!found) continue;
      ++run.detected;
      const double reference = truth->landmarks_3d[30].z() + 20.0;
      const auto mesh = (*camera)->model_vertices();
      for (int l = 17; l < 68; ++l) {
        auto px = color_to_depth_pixel(found->points[static_cast<std::size_t>(l)],
                                       truth->noiseless_depth_mm, registration, reference);
        if (!px) continue;
        const int v = nearest_visible_vertex(*truth, mesh, model.face_vertex_count, k, *px);
        if (v >= 0) hits[static_cast<std::size_t>(l)].push_back(static_cast<std::uint32_t>(v));
      }
    }
  }
  return success();
}

int run_landmarks_embed(const ParsedOptions& options) {
  auto model = load_face_model();
  if (!model) return report_failure(model.error());
  auto guide = load_guide(*model, options.get("guide"));
  if (!guide) return report_failure(guide.error());
  auto detector = load_landmark_detector(options.get("shape-predictor"));
  if (!detector) return report_failure(detector.error());
  auto subjects = options.get_int("subjects");
  auto first = options.get_int("first-seed");
  auto frames = options.get_int("frames");
  auto views = options.get_int("views");
  for (const auto* r : {&subjects, &first, &frames, &views})
    if (!*r) return report_failure(r->error());
  if (*subjects < 1 || *frames < 1 || *views < 1 || *views > *frames)
    return report_failure(
        Error{"--subjects, --frames and --views must be at least 1, --views at most --frames"});
  EmbedRun run;
  Progress progress("landmarks embed", *subjects);
  for (long long s = 0; s < *subjects; ++s) {
    if (auto ok = embed_subject(*model, *guide, *detector, static_cast<std::uint64_t>(*first + s),
                                static_cast<int>(*frames), static_cast<int>(*views),
                                options.get("world"), run);
        !ok)
      return report_failure(ok.error());
    progress.update(s + 1);
  }
  const LandmarkEmbedding learned = learn_landmark_embedding(*model, run.hits);
  const LandmarkEmbedding own = model_landmark_embedding(*model);
  int moved = 0, expression_rows = 0;
  double moved_mm = 0;
  for (const auto& [name, v] : learned.by_expression)
    for (int l = 17; l < 68; ++l)
      expression_rows +=
          v[static_cast<std::size_t>(l)] != learned.vertices[static_cast<std::size_t>(l)];
  for (int l = 17; l < 68; ++l) {
    const auto a = own.vertices[static_cast<std::size_t>(l)],
               b = learned.vertices[static_cast<std::size_t>(l)];
    if (a == b) continue;
    ++moved;
    moved_mm += Eigen::Vector3d(model->neutral[3 * a] - model->neutral[3 * b],
                                model->neutral[3 * a + 1] - model->neutral[3 * b + 1],
                                model->neutral[3 * a + 2] - model->neutral[3 * b + 2])
                    .norm();
  }
  const std::string comment =
      "dlib shape_predictor_68's landmark convention on the face model (iBUG 68 order).\n"
      "Made by: facebooth-lab landmarks embed --subjects " +
      std::to_string(*subjects) + " --first-seed " + std::to_string(*first) + " --frames " +
      std::to_string(*frames) + " --views " + std::to_string(*views) + " --world " +
      options.get("world") + "\n" + std::to_string(run.detected) + " of " +
      std::to_string(run.renders) + " renders with a face found; " + std::to_string(moved) +
      " of 51 interior landmarks moved off the model's vertex;\n" +
      std::to_string(learned.by_expression.size()) + " expressions with their own vertices (" +
      std::to_string(expression_rows) + " rows).";
  const std::string text = format_landmark_embedding(learned, comment);
  const std::string out = options.get("out");
  if (auto ok = write_file_durably(
          out, {reinterpret_cast<const std::uint8_t*>(text.data()), text.size()});
      !ok)
    return report_failure(ok.error());
  std::cout << "{\"renders\": " << run.renders << ", \"detected\": " << run.detected
            << ", \"moved_landmarks\": " << moved
            << ", \"moved_mean_mm\": " << (moved > 0 ? moved_mm / moved : 0.0)
            << ", \"expressions_with_own_vertices\": " << learned.by_expression.size()
            << ", \"expression_rows\": " << expression_rows << ", \"out\": \"" << out << "\"}\n";
  return kExitOk;
}

}  // namespace

std::vector<Command> landmark_embed_commands() {
  return {{{"landmarks embed",
            "learn dlib's landmark convention on the face model (writes the embedding CSV)",
            "Renders textured synthetic subjects (seeds --first-seed.., kept apart from the "
            "evaluations' 1..), every guide expression, --views poses of a head turn each, runs "
            "dlib and records which visible mesh vertex each interior point falls on; per "
            "landmark the median on the mean face, snapped to a vertex, over all expressions "
            "and per expression (kept where it differs). The product reads "
            "DATA_DIR/dlib_landmark_embedding.csv.",
            {{"subjects", "N", "synthetic subjects", "12"},
             {"first-seed", "N", "seed of the first subject", "1000"},
             {"frames", "N", "frames of each head turn", "45"},
             {"views", "N", "frames of each take dlib runs on (spread over the turn)", "3"},
             {"world", "PRESET", "synthetic world preset (world_presets.hpp)", "texture"},
             {"guide", "FILE", "guide recipes (default: DATA_DIR/guide_expressions.json)", ""},
             {"shape-predictor", "FILE", "dlib's 68-point model", ""},
             {"out", "FILE", "the embedding CSV to write", "dlib_landmark_embedding.csv"}}},
           run_landmarks_embed}};
}

}  // namespace fb::cli
