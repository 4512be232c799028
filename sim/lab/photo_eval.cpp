// `facebooth-lab eval photo`: a photograph animated by a take (FaceWarehouse 4.3) and edited
// (4.1), scored against the synthetic camera's truth. Per subject: the synthetic camera renders
// a textured face (frontal, static) playing a known expression track; frame 0 (neutral) is the
// photo. The track's ARKit curves are the take. The product's pipeline (host/cli/
// photo_pipeline.hpp: dlib on the photo, the bilinear fit, eq. 17 blendshapes, the mesh warp)
// animates the photo, and each produced frame is compared with the truth render of the same
// subject making the same expression:
//  - photo_landmark_error_px: dlib on the produced frame against dlib on the truth render (the
//    same detector on both, so its own bias cancels), the 51 inner points (17-67);
//  - the same against the true projected landmarks, dlib's floor on the truth render itself,
//    the model's projected landmarks against the truth, all 68 and inner 51;
//  - the do-nothing baseline: the unanimated photo's dlib points against the truth render's.
// The edit: face_length +N mm on the photo, the model re-fitted to dlib's points on the edited
// photo, face_length measured on both fits' neutral meshes.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iostream>

#include <nlohmann/json.hpp>

#include "algo/bilinear/bootstrap.hpp"
#include "algo/tracking/arkit.hpp"
#include "host/cli/photo_pipeline.hpp"
#include "host/cli/progress.hpp"
#include "host/cli/tracker_setup.hpp"
#include "sim/camera/synthetic_camera.hpp"
#include "sim/camera/world_presets.hpp"
#include "sim/lab/lab_commands.hpp"
#include "storage/asset_files.hpp"
#include "storage/durable_file.hpp"
#include "storage/take_writer.hpp"

namespace fb::cli {

namespace {

using Clock = std::chrono::steady_clock;

// The take's expression track in ARKit curves: neutral, then smoothstep moves between
// keyframes (jaw, smile, blink, brows, pucker, a mix), `hold` frames each.
std::vector<std::array<float, kArkitShapeCount>> photo_take_track(int frames) {
  auto idx = [](std::string_view n) {
    return static_cast<int>(std::find(kArkitNames.begin(), kArkitNames.end(), n) -
                            kArkitNames.begin());
  };
  using Key = std::vector<std::pair<std::string_view, float>>;
  const std::vector<Key> keys = {
      {},
      {{"jawOpen", 0.7f}},
      {{"mouthSmileLeft", 0.9f}, {"mouthSmileRight", 0.9f}},
      {{"eyeBlinkLeft", 1.0f}, {"eyeBlinkRight", 1.0f}, {"browInnerUp", 0.6f}},
      {{"browInnerUp", 0.9f}, {"browOuterUpLeft", 0.8f}, {"browOuterUpRight", 0.8f}},
      {{"mouthPucker", 0.8f}, {"mouthFunnel", 0.4f}},
      {{"jawOpen", 0.4f}, {"mouthSmileLeft", 0.6f}, {"mouthStretchRight", 0.5f}},
      {}};
  std::vector<std::array<float, kArkitShapeCount>> key_weights(keys.size());
  for (std::size_t k = 0; k < keys.size(); ++k) {
    key_weights[k].fill(0.0f);
    for (const auto& [name, w] : keys[k]) key_weights[k][static_cast<std::size_t>(idx(name))] = w;
  }
  std::vector<std::array<float, kArkitShapeCount>> out(static_cast<std::size_t>(frames));
  const double span = static_cast<double>(frames - 1) / static_cast<double>(keys.size() - 1);
  for (int f = 0; f < frames; ++f) {
    const double u = f / span;
    const auto k = std::min(keys.size() - 2, static_cast<std::size_t>(u));
    double t = std::clamp(u - static_cast<double>(k), 0.0, 1.0);
    t = t * t * (3 - 2 * t);
    for (int c = 0; c < kArkitShapeCount; ++c)
      out[static_cast<std::size_t>(f)][static_cast<std::size_t>(c)] =
          static_cast<float>((1 - t) * key_weights[k][static_cast<std::size_t>(c)] +
                             t * key_weights[k + 1][static_cast<std::size_t>(c)]);
  }
  return out;
}

struct SubjectRender {
  std::vector<ColorImage> frames;
  std::vector<std::array<Eigen::Vector2d, 68>> truth;  // true landmarks, colour px
  TakeData take;
};

Result<SubjectRender> render_subject(const FaceModel& model, std::uint64_t seed, int frames,
                                     double distance_mm) {
  const auto track = photo_take_track(frames);
  auto mapping = make_arkit_mapping(model);
  if (!mapping) return mapping.failure();
  SyntheticOptions so;
  so.seed = seed;
  so.motion = SyntheticMotion::kStatic;
  so.frame_count = frames;
  so.distance_mm = distance_mm;
  so.sensor.depth_noise = false;
  if (auto ok = apply_world_preset("texture", seed, so); !ok) return ok.failure();
  TakeWriter writer(std::vector<std::string>(kArkitNames.begin(), kArkitNames.end()), 30.0);
  for (int f = 0; f < frames; ++f) {
    std::vector<float> w(model.expression_names.size(), 0.0f);
    mapping->to_model(track[static_cast<std::size_t>(f)], w);
    so.expression_track.push_back(w);
    if (auto ok = writer.add_frame(f / 30.0, RigidPose{}, track[static_cast<std::size_t>(f)]); !ok)
      return ok.failure();
  }
  auto camera = make_synthetic_camera(model, so);
  if (!camera) return camera.failure();
  if (auto ok = (*camera)->start(); !ok) return ok.failure();
  SubjectRender out;
  out.take = writer.data();
  RgbdFrame frame;
  for (int f = 0; f < frames; ++f) {
    auto st = (*camera)->next_frame(frame, std::chrono::milliseconds(1000));
    if (!st) return st.failure();
    const FrameTruth* truth = (*camera)->truth();
    if (*st != FrameStatus::kFrame || truth == nullptr || truth->landmarks_color_px.size() != 68)
      return fail("eval photo: the synthetic camera gave no frame " + std::to_string(f));
    out.frames.push_back(frame.color);
    std::array<Eigen::Vector2d, 68> t;
    std::copy(truth->landmarks_color_px.begin(), truth->landmarks_color_px.end(), t.begin());
    out.truth.push_back(t);
  }
  return out;
}

Result<BilinearModel> eval_model(const ParsedOptions& options, const FaceModel& face_model) {
  if (const std::string path = options.get("model"); !path.empty()) {
    auto bytes = read_file_bytes(path);
    if (!bytes) return bytes.failure();
    return parse_bilinear_model(std::as_bytes(std::span(*bytes)));
  }
  // As `facebooth model build --from-face-model --exp-knobs 54` (150 identities, seed 1).
  std::cerr << "eval photo: building the bootstrap bilinear model (150 identities, 50 x 54)\n";
  const auto ids = draw_identities(face_model, 150, 1);
  const FactoredTensor tensor = bootstrap_tensor(face_model, ids);
  auto factors = mode_factors(tensor);
  if (!factors) return factors.failure();
  auto truncated = truncate(tensor, *factors, 50, 54);
  if (!truncated) return truncated.failure();
  return make_bilinear_model(*truncated, face_model, bootstrap_expression_names(face_model),
                             "{\"source\":\"eval photo\"}");
}

// Mean distance over points first..67 (only where both are valid).
double mean_distance(const std::array<Eigen::Vector2d, 68>& a,
                     const std::array<Eigen::Vector2d, 68>& b, int first) {
  double s = 0;
  for (int k = first; k < 68; ++k)
    s += (a[static_cast<std::size_t>(k)] - b[static_cast<std::size_t>(k)]).norm();
  return s / (68 - first);
}

struct Sums {
  double n = 0, produced_vs_truth_dlib = 0, produced_vs_truth_dlib_all = 0,
         produced_vs_true_points = 0, dlib_floor = 0, projected = 0, projected_all = 0,
         baseline = 0, motion = 0, worst_frame = 0;
  int dlib_misses = 0;
  // Frames whose true inner landmarks moved more than 3 px on average from the photo's.
  double moving_n = 0, moving_error = 0, moving_baseline = 0, moving_motion = 0;
  std::vector<double> per_frame;  // the first subject's photo_landmark_error_px per frame
};

std::array<Eigen::Vector2d, 68> projected_landmarks(const BilinearModel& m, const PhotoFace& face,
                                                    std::span<const float> mesh) {
  std::array<Eigen::Vector2d, 68> out;
  for (int k = 0; k < 68; ++k) {
    const std::uint32_t v = m.landmark_vertices[static_cast<std::size_t>(k)];
    out[static_cast<std::size_t>(k)] =
        face.fit.pose.project(Eigen::Vector3d(mesh[3 * v], mesh[3 * v + 1], mesh[3 * v + 2]));
  }
  return out;
}

// Scores one subject's animation; fills `produced` with the frames for pictures.
Result<void> score_animation(const BilinearModel& model, LandmarkDetector& detector,
                             const SubjectRender& r, const PhotoFace& face, bool keep_expression,
                             const std::array<Eigen::Vector2d, 68>& photo_points,
                             const std::vector<std::vector<float>>& beta, Sums& sums,
                             std::vector<ColorImage>& produced) {
  const auto triangles = face_region_triangles(model);
  std::vector<float> mesh;
  for (std::size_t f = 0; f < r.frames.size(); ++f) {
    auto frame = animate_photo_frame(r.frames.front(), model, face, triangles, beta[f],
                                     keep_expression, mesh);
    if (!frame) return frame.failure();
    const auto projected = projected_landmarks(model, face, mesh);
    auto on_truth = detect_photo_landmarks(detector, r.frames[f], "truth frame");
    auto on_produced = detect_photo_landmarks(detector, *frame, "produced frame");
    produced.push_back(std::move(*frame));
    if (f == 0) continue;  // the photo itself
    if (!on_truth || !on_produced) {
      ++sums.dlib_misses;
      continue;
    }
    const double e = mean_distance(on_produced->points, on_truth->points, 17);
    sums.n += 1;
    sums.produced_vs_truth_dlib += e;
    sums.worst_frame = std::max(sums.worst_frame, e);
    if (sums.per_frame.size() + 1 < r.frames.size()) sums.per_frame.push_back(e);
    sums.produced_vs_truth_dlib_all += mean_distance(on_produced->points, on_truth->points, 0);
    sums.produced_vs_true_points += mean_distance(on_produced->points, r.truth[f], 17);
    sums.dlib_floor += mean_distance(on_truth->points, r.truth[f], 17);
    sums.projected += mean_distance(projected, r.truth[f], 17);
    sums.projected_all += mean_distance(projected, r.truth[f], 0);
    sums.baseline += mean_distance(photo_points, on_truth->points, 17);
    const double motion = mean_distance(r.truth[0], r.truth[f], 17);
    sums.motion += motion;
    if (motion > 3.0) {
      sums.moving_n += 1;
      sums.moving_error += e;
      sums.moving_baseline += mean_distance(photo_points, on_truth->points, 17);
      sums.moving_motion += motion;
    }
  }
  return success();
}

// FaceWarehouse 4.4: subject `seed` plays the eval's track; dlib on its frames, the identity
// fitted jointly over them, the per-frame coefficients (photo_pipeline's video_coefficients).
Result<std::vector<std::vector<float>>> video_take(const BilinearModel& model,
                                                   LandmarkDetector& detector,
                                                   const FaceModel& face_model, std::uint64_t seed,
                                                   int frames, double distance, double& fit_error) {
  auto video = render_subject(face_model, seed, frames, distance);
  if (!video) return video.failure();
  std::vector<ImageLandmarks> points(video->frames.size());
  std::vector<bool> found(video->frames.size(), false);
  for (std::size_t f = 0; f < video->frames.size(); ++f) {
    auto l = detect_photo_landmarks(detector, video->frames[f], "video frame");
    if (!l) continue;
    points[f] = *l;
    found[f] = true;
  }
  auto c = video_coefficients(model, points, found);
  if (!c) return c.failure();
  fit_error += c->mean_fit_error_px;
  return c->coefficients.beta;
}

struct EditScore {
  double requested_mm = 0, model_change_mm = 0, refit_change_mm = 0, dlib_change_mm = 0,
         projected_change_mm = 0;
};

// face_length +requested on the photo; re-fitted on dlib's points of the edited photo.
Result<EditScore> score_edit(const BilinearModel& model, LandmarkDetector& detector,
                             const ColorImage& photo, const ImageLandmarks& points,
                             const PhotoFace& face, double requested, ColorImage& edited_out) {
  const auto attributes = default_attributes();
  auto regression = fit_attribute_regression(model, attributes);
  if (!regression) return regression.failure();
  std::vector<double> change(attributes.size(), 0.0);
  change[0] = requested;  // face_length
  const auto w_id = apply_attribute_change(*regression, face.fit.w_id, change);
  std::vector<float> edited(face.mesh.size()), neutral(face.mesh.size());
  model.evaluate(w_id, face.fit.w_exp, edited);
  auto image =
      warp_face(photo, model, face.fit.pose, face.mesh, edited, face_region_triangles(model),
                MeshWarpOptions{.mouth_cavity = false});  // as photo edit
  if (!image) return image.failure();
  auto length = [&](std::span<const float> id) {
    model.evaluate(id, model.expression_row(0), neutral);
    return measure_attributes(neutral, model.landmark_vertices, attributes)[0];
  };
  EditScore s;
  s.requested_mm = requested;
  s.model_change_mm = length(w_id) - length(face.fit.w_id);
  // What the warp should show: landmarks 27 - 8 of the fitted and edited meshes, projected.
  auto projected = [&](std::span<const float> mesh) {
    const auto a = model.landmark_vertices[27], b = model.landmark_vertices[8];
    return (face.fit.pose.project({mesh[3 * a], mesh[3 * a + 1], mesh[3 * a + 2]}) -
            face.fit.pose.project({mesh[3 * b], mesh[3 * b + 1], mesh[3 * b + 2]}))
        .norm();
  };
  s.projected_change_mm = (projected(edited) - projected(face.mesh)) / face.fit.pose.scale;
  auto l = detect_photo_landmarks(detector, *image, "edited photo");
  if (!l) return l.failure();
  auto refit = fit_photo_face(model, *l);
  if (!refit) return refit.failure();
  // In the photo's px over its scale: weak perspective leaves the re-fit's size to the prior
  // (s and |w_id| trade off), so its mm alone would hide a longer face in a smaller scale.
  s.refit_change_mm = (refit->fit.pose.scale * length(refit->fit.w_id) -
                       face.fit.pose.scale * length(face.fit.w_id)) /
                      face.fit.pose.scale;
  auto px = [](const ImageLandmarks& m) { return (m.points[27] - m.points[8]).norm(); };
  s.dlib_change_mm = (px(*l) - px(points)) / face.fit.pose.scale;
  edited_out = std::move(*image);
  return s;
}

// Photo | produced frames (top) over truth renders (bottom), cropped around the face.
ColorImage comparison_picture(const SubjectRender& r, const std::vector<ColorImage>& produced,
                              const std::vector<int>& at) {
  const auto& t = r.truth.front();
  double x0 = 1e9, x1 = -1e9, y0 = 1e9, y1 = -1e9;
  for (const auto& p : t) {
    x0 = std::min(x0, p.x());
    x1 = std::max(x1, p.x());
    y0 = std::min(y0, p.y());
    y1 = std::max(y1, p.y());
  }
  const int half = static_cast<int>(0.8 * std::max(x1 - x0, y1 - y0));
  const int cx = static_cast<int>((x0 + x1) / 2),
            cy = static_cast<int>((y0 + y1) / 2 - 0.1 * (y1 - y0));
  const int size = 2 * half, cols = static_cast<int>(at.size());
  ColorImage out;
  out.resize(cols * (size + 4), 2 * size + 4);
  std::fill(out.pixels.begin(), out.pixels.end(), Rgb8{255, 255, 255});
  for (int c = 0; c < cols; ++c)
    for (int row = 0; row < 2; ++row) {
      const ColorImage& src =
          row == 0 ? produced[static_cast<std::size_t>(at[static_cast<std::size_t>(c)])]
                   : r.frames[static_cast<std::size_t>(at[static_cast<std::size_t>(c)])];
      for (int y = 0; y < size; ++y)
        for (int x = 0; x < size; ++x)
          out.at(c * (size + 4) + x, row * (size + 4) + y) =
              src.at(std::clamp(cx - half + x, 0, src.width - 1),
                     std::clamp(cy - half + y, 0, src.height - 1));
    }
  return out;
}

// --out DIR: the first subject's photo and its take in a store, for `facebooth photo animate`.
Result<TakeId> write_inputs(const std::filesystem::path& dir, const SubjectRender& r) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) return fail("cannot create " + dir.string() + ": " + ec.message());
  if (auto w = write_photo(r.frames.front(), dir / "photo.png"); !w) return w.failure();
  auto store = SessionStore::open(dir / "store");
  if (!store) return store.failure();
  auto subject = store->add_subject("eval photo take");
  if (!subject) return subject.failure();
  TakeData take = r.take;
  take.info.subject = *subject;
  return store->add_take(take);
}

// The mean of the subjects' edit figures.
EditScore mean_edit(const std::vector<EditScore>& edits) {
  EditScore e;
  const double n = static_cast<double>(std::max<std::size_t>(1, edits.size()));
  for (const auto& x : edits) {
    e.requested_mm += x.requested_mm / n;
    e.model_change_mm += x.model_change_mm / n;
    e.refit_change_mm += x.refit_change_mm / n;
    e.dlib_change_mm += x.dlib_change_mm / n;
    e.projected_change_mm += x.projected_change_mm / n;
  }
  return e;
}

// --png (the first subject's frames beside the produced ones) and --out (its inputs and edit).
Result<void> write_first_subject(const ParsedOptions& options, const SubjectRender& r,
                                 const std::vector<ColorImage>& produced, const ColorImage& edited,
                                 nlohmann::json& out) {
  if (const std::string png = options.get("png"); !png.empty()) {
    const int n = static_cast<int>(r.frames.size());
    if (auto w = write_photo(
            comparison_picture(r, produced, {0, n / 7, 2 * n / 7, 3 * n / 7 + 1, 4 * n / 7 + 1}),
            png);
        !w)
      return w.failure();
  }
  if (const std::string dir = options.get("out"); !dir.empty()) {
    auto take = write_inputs(dir, r);
    if (!take) return take.failure();
    if (auto w = write_photo(edited, std::filesystem::path(dir) / "edited.png"); !w)
      return w.failure();
    out["out"] = {{"photo", dir + "/photo.png"}, {"store", dir + "/store"}, {"take", *take}};
  }
  return success();
}

int run_eval_photo(const ParsedOptions& options) {
  auto subjects = options.get_int("subjects");
  auto frames = options.get_int("frames");
  auto distance = options.get_double("distance");
  auto edit_mm = options.get_double("edit-mm");
  if (!subjects || !frames || !distance || !edit_mm || *subjects < 1 || *frames < 8)
    return report_failure({"--subjects >= 1, --frames >= 8, --distance and --edit-mm numbers"});
  auto face_model = load_face_model();
  if (!face_model) return report_failure(face_model.error());
  auto detector = load_landmark_detector("");
  if (!detector) return report_failure(detector.error());
  const auto t0 = Clock::now();
  auto model = eval_model(options, *face_model);
  if (!model) return report_failure(model.error());
  const double model_s = std::chrono::duration<double>(Clock::now() - t0).count();
  Sums sums, video_sums;
  double fit_error = 0, animate_ms = 0, video_fit = 0;
  std::vector<EditScore> edits;
  nlohmann::json out;
  Progress progress("eval photo", *subjects);
  for (int s = 0; s < *subjects; ++s) {
    const auto seed = static_cast<std::uint64_t>(101 + s);
    auto r = render_subject(*face_model, seed, static_cast<int>(*frames), *distance);
    if (!r) return report_failure(r.error());
    auto points = detect_photo_landmarks(*detector, r->frames.front(), "the photo");
    if (!points) return report_failure(points.error());
    auto face = fit_photo_face(*model, *points);
    if (!face) return report_failure(face.error());
    fit_error += face->fit.mean_error_px;
    std::vector<ColorImage> produced;
    const bool keep = !options.flag("replace-expression");
    auto coefficients = take_coefficients(r->take, *model);
    if (!coefficients) return report_failure(coefficients.error());
    const auto ta = Clock::now();
    if (auto ok = score_animation(*model, *detector, *r, *face, keep, points->points,
                                  coefficients->beta, sums, produced);
        !ok)
      return report_failure(ok.error());
    animate_ms += 1000 * std::chrono::duration<double>(Clock::now() - ta).count() /
                  static_cast<double>(r->frames.size());
    if (!options.flag("no-video")) {
      // 4.4: another subject's video of the same track drives the photo.
      auto video = video_take(*model, *detector, *face_model, seed + 50, static_cast<int>(*frames),
                              *distance, video_fit);
      if (!video) return report_failure(video.error());
      std::vector<ColorImage> unused;
      if (auto ok = score_animation(*model, *detector, *r, *face, keep, points->points, *video,
                                    video_sums, unused);
          !ok)
        return report_failure(ok.error());
    }
    ColorImage edited;
    auto edit = score_edit(*model, *detector, r->frames.front(), *points, *face, *edit_mm, edited);
    if (!edit) return report_failure(edit.error());
    edits.push_back(*edit);
    if (s == 0)
      if (auto ok = write_first_subject(options, *r, produced, edited, out); !ok)
        return report_failure(ok.error());
    progress.update(s + 1);
  }
  const double n = std::max(1.0, sums.n);
  const EditScore e = mean_edit(edits);
  out.update({{"subjects", *subjects},
              {"frames_per_subject", *frames},
              {"frames_scored", sums.n},
              {"dlib_misses", sums.dlib_misses},
              {"model",
               {{"id_knobs", model->id_knobs},
                {"exp_knobs", model->exp_knobs},
                {"identities", model->identity_count},
                {"build_s", model_s}}},
              {"photo_fit_error_px", fit_error / *subjects},
              {"photo_landmark_error_px", sums.produced_vs_truth_dlib / n},
              {"photo_landmark_error_worst_frame_px", sums.worst_frame},
              {"photo_landmark_error_all68_px", sums.produced_vs_truth_dlib_all / n},
              {"photo_landmark_error_vs_true_points_px", sums.produced_vs_true_points / n},
              {"dlib_error_on_truth_render_px", sums.dlib_floor / n},
              {"projected_model_landmark_error_px", sums.projected / n},
              {"projected_model_landmark_error_all68_px", sums.projected_all / n},
              {"unanimated_photo_error_px", sums.baseline / n},
              {"expression_motion_px", sums.motion / n},
              {"animate_ms_per_frame", animate_ms / *subjects},
              {"edit_face_length_requested_mm", e.requested_mm},
              {"edit_face_length_model_change_mm", e.model_change_mm},
              {"edit_face_length_refit_change_mm", e.refit_change_mm},
              {"edit_face_length_dlib_change_mm", e.dlib_change_mm},
              {"edit_face_length_projected_change_mm", e.projected_change_mm},
              {"budget", {{"photo_landmark_error_px", "<= 3"}}}});
  out["photo_landmark_error_per_frame_first_subject_px"] = sums.per_frame;
  if (!options.flag("no-video")) {
    const double vn = std::max(1.0, video_sums.n);
    out["video"] = {{"photo_landmark_error_px", video_sums.produced_vs_truth_dlib / vn},
                    {"worst_frame_px", video_sums.worst_frame},
                    {"unanimated_photo_error_px", video_sums.baseline / vn},
                    {"joint_fit_error_px", video_fit / *subjects},
                    {"frames_scored", video_sums.n},
                    {"dlib_misses", video_sums.dlib_misses}};
  }
  const double moving = std::max(1.0, sums.moving_n);
  out["moving_frames"] = {{"frames", sums.moving_n},
                          {"photo_landmark_error_px", sums.moving_error / moving},
                          {"unanimated_photo_error_px", sums.moving_baseline / moving},
                          {"expression_motion_px", sums.moving_motion / moving}};
  out["met"] = sums.n > 0 && sums.produced_vs_truth_dlib / n <= 3.0;
  std::cout << out.dump(2) << "\n";
  return kExitOk;
}

}  // namespace

std::vector<Command> photo_eval_commands() {
  return {
      {{"eval photo",
        "a photograph animated by a take and edited, against the synthetic truth (JSON)",
        "Per subject a textured synthetic face (frontal, static) plays a known expression "
        "track; frame 0 is the photo, the track's ARKit curves the take. The photo is "
        "animated as `facebooth photo animate` does and each frame compared with the truth "
        "render of the same expression: photo_landmark_error_px is dlib on the produced frame "
        "against dlib on the truth render (inner 51 points); the JSON also gives it against "
        "the true points, dlib's own error on the truth render, the model's projected "
        "landmarks, and the unanimated photo (baseline). The edit: face_length +--edit-mm on "
        "the photo as `facebooth photo edit` does, measured on the model re-fitted to the "
        "edited photo. --out DIR writes the first subject's photo.png, edited.png and a store "
        "with its take; --png the photo and frames over the truth renders.",
        {{"subjects", "N", "synthetic subjects", "3"},
         {"frames", "N", "take length (frames)", "36"},
         {"distance", "MM", "face distance from the camera", "550"},
         {"edit-mm", "MM", "face_length change of the edit", "10"},
         {"model", "FILE", "bilinear model (default: the bootstrap, 150 ids, 50 x 54, built)", ""},
         {"replace-expression", "", "as photo animate --replace-expression", ""},
         {"no-video", "", "skip the video part (4.4: another subject's frames drive the photo)",
          ""},
         {"out", "DIR", "write the photo, the edited photo and the take's store here", ""},
         {"png", "FILE", "picture: produced frames over the truth renders", ""},
         {"json", "", "JSON output (the only output)", ""}}},
       run_eval_photo}};
}

}  // namespace fb::cli
