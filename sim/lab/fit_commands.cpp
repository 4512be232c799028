// facebooth-lab eval fit | bench fit: the landmark and face-fitting stage
// (FaceWarehouse 3.2.1-3.2.2, algo/landmarks + algo/fitting + algo/guide) scored on synthetic
// subjects with ground truth. One JSON object on stdout, progress on stderr.
//
// Eval pipeline per subject and expression: synthetic head-turn take (random identity, the
// guide recipe's weights, sensor noise on) -> KinectFusion (algo/fusion) -> ray-cast frontal
// depth + normals -> landmarks (ground-truth colour points + Gaussian pixel noise, lifted with
// the registration and the fused depth) -> neutral fit / deformation transfer + refinement.
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <numeric>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <sstream>

#include "algo/core/clock.hpp"
#include "algo/core/figure_text.hpp"
#include "algo/fitting/expression_transfer.hpp"
#include "algo/fitting/face_fit.hpp"
#include "algo/fitting/fit_qa.hpp"
#include "algo/fusion/face_fusion.hpp"
#include "algo/guide/guide_expressions.hpp"
#include "algo/landmarks/landmark_detector.hpp"
#include "algo/landmarks/landmark_lifting.hpp"
#include "algo/render/rasterizer.hpp"
#include "host/cli/stats.hpp"
#include "sim/camera/synthetic_camera.hpp"
#include "sim/camera/world_presets.hpp"
#include "sim/lab/lab_commands.hpp"
#include "sim/scoring/fit_metrics.hpp"
#include "sim/subject/synthetic_capture.hpp"
#include "sim/subject/unit_calibration.hpp"
#include "storage/asset_files.hpp"

namespace fb::cli {
namespace {

constexpr const char* kShapePredictorDefault =
    "/usr/share/dlib/shape_predictor_68_face_landmarks.dat";

// The shape predictor: the plain .dat, or a .dat.bz2 decompressed once into a cache directory.
Result<LandmarkDetector> load_detector(const std::string& option) {
  std::filesystem::path path = option.empty() ? kShapePredictorDefault : option;
  if (!std::filesystem::exists(path) && std::filesystem::exists(path.string() + ".bz2"))
    path += ".bz2";
  if (path.extension() == ".bz2") {
    const char* xdg = std::getenv("XDG_CACHE_HOME");
    const char* home = std::getenv("HOME");
    const std::filesystem::path cache =
        xdg ? std::filesystem::path(xdg) / "facebooth"
            : std::filesystem::path(home ? home : "/tmp") / ".cache" / "facebooth";
    const std::filesystem::path out = cache / path.stem();
    if (!std::filesystem::exists(out)) {
      std::error_code ec;
      std::filesystem::create_directories(cache, ec);
      std::cerr << "landmarks: decompressing " << path << " into " << out << " (once)...\n";
      const std::string tmp = out.string() + ".part";
      const std::string cmd = "bzip2 -dc '" + path.string() + "' > '" + tmp + "'";
      if (std::system(cmd.c_str()) != 0) return fail("could not decompress " + path.string());
      std::filesystem::rename(tmp, out, ec);
      if (ec) return fail("could not write " + out.string());
    }
    path = out;
  }
  std::ifstream in(path, std::ios::binary);
  if (!in)
    return fail("cannot read the landmark model " + path.string() +
                " (install Debian's libdlib-data or pass --shape-predictor)");
  return LandmarkDetector::create(in);
}

// ---------------------------------------------------------------------------------------------
// Error maps (paper Fig. 2 style): |mesh depth - fused depth| per pixel over the face.

cv::Mat error_panel(const FaceModel& model, std::span<const float> mesh, const RigidPose& pose,
                    const Capture& c, const FaceBox& box, double scale_mm, const std::string& title,
                    double rms) {
  std::vector<Eigen::Vector3f> v(static_cast<std::size_t>(model.vertex_count));
  for (int i = 0; i < model.vertex_count; ++i)
    v[static_cast<std::size_t>(i)] =
        pose.apply({mesh[3 * i], mesh[3 * i + 1], mesh[3 * i + 2]}).cast<float>();
  // Face triangles only (all three vertices in the face region).
  std::vector<std::uint32_t> tris;
  for (std::size_t t = 0; t + 2 < model.triangles.size(); t += 3)
    if (model.triangles[t] < static_cast<std::uint32_t>(model.face_vertex_count) &&
        model.triangles[t + 1] < static_cast<std::uint32_t>(model.face_vertex_count) &&
        model.triangles[t + 2] < static_cast<std::uint32_t>(model.face_vertex_count))
      tris.insert(tris.end(), {model.triangles[t], model.triangles[t + 1], model.triangles[t + 2]});
  RasterBuffers rb;
  rb.reset(c.intrinsics.width, c.intrinsics.height);
  (void)rasterize(c.intrinsics, v, tris, RasterOptions{}, rb);
  cv::Mat out(box.height, box.width, CV_8UC3, cv::Scalar(0, 0, 0));
  for (int y = 0; y < box.height; ++y)
    for (int x = 0; x < box.width; ++x) {
      const int px = box.x + x, py = box.y + y;
      if (!rb.covered(px, py)) continue;
      const float f = c.fused.depth_mm.at(px, py);
      if (!(f > 0)) {
        out.at<cv::Vec3b>(y, x) = {60, 60, 60};
        continue;
      }
      const double e = std::abs(rb.depth[rb.index(px, py)] - f);
      cv::Mat p(1, 1, CV_8U, cv::Scalar(std::clamp(e / scale_mm, 0.0, 1.0) * 255.0));
      cv::Mat col;
      cv::applyColorMap(p, col, cv::COLORMAP_JET);
      out.at<cv::Vec3b>(y, x) = col.at<cv::Vec3b>(0, 0);
    }
  cv::Mat big;
  cv::resize(out, big, cv::Size(), 2.0, 2.0, cv::INTER_NEAREST);
  cv::Mat framed(big.rows + 30, big.cols, CV_8UC3, cv::Scalar(255, 255, 255));
  big.copyTo(framed(cv::Rect(0, 30, big.cols, big.rows)));
  char text[160];
  std::snprintf(text, sizeof text, "%s: RMS %s mm (0-%.1f mm)", title.c_str(),
                figure_text(rms).c_str(), scale_mm);
  cv::putText(framed, text, cv::Point(4, 20), cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 0),
              1, cv::LINE_AA);
  return framed;
}

Result<void> write_png(const std::filesystem::path& path, const cv::Mat& image) {
  try {
    if (!cv::imwrite(path.string(), image)) return fail("could not write " + path.string());
  } catch (const cv::Exception& e) {
    return fail("could not write " + path.string() + ": " + e.what());
  }
  return success();
}

// ---------------------------------------------------------------------------------------------
// facebooth-lab eval fit

Result<std::vector<int>> parse_expression_list(const std::string& text, const GuideSet& guide) {
  std::vector<int> out;
  if (text.empty() || text == "all") {
    for (std::size_t i = 0; i < guide.expressions.size(); ++i) out.push_back(static_cast<int>(i));
    return out;
  }
  std::stringstream s(text);
  std::string item;
  out.push_back(0);
  while (std::getline(s, item, ',')) {
    int id = guide.find(item);
    if (id < 0) {
      try {
        id = std::stoi(item);
      } catch (...) {
        id = -1;
      }
    }
    if (id < 0 || id >= static_cast<int>(guide.expressions.size()))
      return fail("--expressions: unknown expression '" + item + "' (names or ids 0-19, or all)");
    if (id != 0) out.push_back(id);
  }
  return out;
}

// One run of eval fit over the subjects, in the world `world` (a world_presets.hpp part, or
// empty for the plain synthetic camera).
struct FitEvalSetup {
  const FaceModel* model = nullptr;
  const GuideSet* guide = nullptr;
  const RefineSystem* model_system = nullptr;
  LandmarkDetector* detector = nullptr;  // dlib (scored, and the fit's landmarks with dlib_fit)
  std::vector<int> expressions;
  long long identities = 1, first_seed = 1, frames = 45;
  double noise = 1, robust_noise = 5;
  bool noiseless_depth = false;
  bool dlib_fit = false;  // fit dlib's points on frame 0's colour image instead of truth + noise
  // The mesh vertices dlib's points mark (with dlib_fit); unset = the model's landmark vertices.
  std::optional<LandmarkEmbedding> embedding;
  UnitCalibration unit_calibration = UnitCalibration::kSelfCalibrated;
};

nlohmann::json vertex_error_json(const VertexErrorParts& p) {
  return {{"mean_offset_mm", {p.mean_offset_mm.x(), p.mean_offset_mm.y(), p.mean_offset_mm.z()}},
          {"after_translation_mm", p.after_translation_mm},
          {"after_rigid_mm", p.after_rigid_mm},
          {"rigid_rotation_deg", p.rigid_rotation_deg},
          {"normal_mm", p.normal_mm},
          {"tangential_mm", p.tangential_mm}};
}

// dlib's error by landmark group (iBUG 68): the mean error length and the length of the mean
// error vector (what all captures share: a convention, not noise), px, averaged over the group.
nlohmann::json landmark_group_errors(const std::array<Eigen::Vector2d, 68>& bias_sum,
                                     const std::array<double, 68>& len_sum, int n) {
  if (n == 0) return nullptr;
  const std::array<std::pair<const char*, std::pair<int, int>>, 5> groups{{{"contour", {0, 16}},
                                                                           {"brows", {17, 26}},
                                                                           {"nose", {27, 35}},
                                                                           {"eyes", {36, 47}},
                                                                           {"mouth", {48, 67}}}};
  nlohmann::json out = nlohmann::json::object();
  for (const auto& [name, range] : groups) {
    double len = 0, bias = 0;
    for (int l = range.first; l <= range.second; ++l) {
      len += len_sum[static_cast<std::size_t>(l)] / n;
      bias += (bias_sum[static_cast<std::size_t>(l)] / n).norm();
    }
    const int count = range.second - range.first + 1;
    out[name] = {{"error_px", len / count}, {"bias_px", bias / count}};
  }
  return out;
}

Result<nlohmann::json> eval_fit_once(const ParsedOptions& options, const FitEvalSetup& setup,
                                     const std::string& world) {
  const FaceModel* model = setup.model;
  const GuideSet* guide = setup.guide;
  const RefineSystem* model_system = setup.model_system;
  const std::vector<int>* expressions = &setup.expressions;
  const long long* identities = &setup.identities;
  const long long* first_seed = &setup.first_seed;
  const long long* frames = &setup.frames;
  const double* noise = &setup.noise;
  const double* robust_noise = &setup.robust_noise;
  const bool noiseless_depth = setup.noiseless_depth;
  LandmarkDetector* detector = setup.detector;
  // In a world (scenario runs) a capture that fails (fusion loses the face, dlib finds none, a
  // fit fails) is a figure, not an abort: it is counted and its reason kept.
  const bool lenient = !world.empty();
  int captures = 0, captures_failed = 0;
  std::map<std::string, int> failure_reasons;
  Samples rms_init, rms_ref, ne_init, ne_ref, ne_noise, ee_init, ee_ref, erms_ref, lm_err,
      lm_err_interior, lm_detect_fail, neutral_ms, expr_ms, lm_ms_track, lm_ms_full, lift_err;
  int detections = 0, detection_attempts = 0, fit_dlib_found = 0, fit_dlib_attempts = 0;
  Samples fit_dlib_err;
  // dlib's error per landmark over the captures: the mean vector (bias: a convention the model's
  // landmark vertices do not share) and the mean length (bias + scatter).
  std::array<Eigen::Vector2d, 68> dlib_bias_sum;
  dlib_bias_sum.fill(Eigen::Vector2d::Zero());
  std::array<double, 68> dlib_len_sum{};
  nlohmann::json per_subject = nlohmann::json::array();
  nlohmann::json per_expression = nlohmann::json::object();
  std::map<int, Samples> expr_err;
  const double scale = 3.0;
  const std::vector<std::uint32_t> eye_mouth = eye_mouth_vertices(*model);
  std::vector<double> eye_mouth_err;
  int qa_passed = 0;
  int frames_fused = 0, frames_dropped = 0, boxes_detected = 0;
  for (long long s = 0; s < *identities; ++s) {
    const std::uint64_t seed = static_cast<std::uint64_t>(*first_seed + s);
    const std::vector<float> identity = identity_draw(seed, model->identity_count);
    std::mt19937_64 rng(seed * 7919 + 17);
    nlohmann::json subject;
    subject["seed"] = seed;
    std::optional<ExpressionTransfer> transfer;
    FitResult neutral;
    std::vector<float> g0;
    nlohmann::json exprs = nlohmann::json::array();
    for (int e : *expressions) {
      const GuideExpression& ge = guide->expressions[static_cast<std::size_t>(e)];
      auto weights = guide_weights(ge, *model);
      if (!weights) return weights.failure();
      std::cerr << "eval fit: subject " << seed << ", " << ge.name << " ...\n";
      nlohmann::json j;
      j["expression"] = ge.name;
      ++captures;
      // Why a capture gave no figure: an error outside a world, a counted failure in one.
      auto failed = [&](const std::string& stage, const Error& error) -> Result<bool> {
        if (!lenient) return fail(error);
        ++captures_failed;
        ++failure_reasons[stage];
        j["failed"] = stage + ": " + error.message;
        exprs.push_back(j);
        std::cerr << "  " << ge.name << " failed at " << stage << ": " << error.message << "\n";
        return e == 0;  // no neutral: the subject's expressions cannot be fitted
      };
      auto cap = capture(*model, identity, *weights, seed * 1000 + static_cast<std::uint64_t>(e),
                         static_cast<int>(*frames), detector && e == 0 && s == 0, {}, world, seed,
                         setup.unit_calibration, detector);
      if (!cap) {
        auto stop = failed("capture", cap.error());
        if (!stop) return stop.failure();
        if (*stop) break;
        continue;
      }
      std::vector<Eigen::Vector2d> fit_points = noisy(cap->truth_color_px, *noise, rng);
      if (setup.dlib_fit) {
        // What runs on real frames: dlib on the colour image of frame 0.
        ++fit_dlib_attempts;
        detector->reset_tracking();
        auto found = detector->detect(cap->color);
        if (!found) {
          auto stop = failed("dlib", found.error());
          if (!stop) return stop.failure();
          if (*stop) break;
          continue;
        }
        ++fit_dlib_found;
        fit_points.assign(found->points.begin(), found->points.end());
        double sum = 0;
        for (int l = 0; l < 68; ++l) {
          const Eigen::Vector2d d = fit_points[static_cast<std::size_t>(l)] -
                                    cap->truth_color_px[static_cast<std::size_t>(l)];
          sum += d.norm();
          dlib_bias_sum[static_cast<std::size_t>(l)] += d;
          dlib_len_sum[static_cast<std::size_t>(l)] += d.norm();
        }
        fit_dlib_err.add(sum / 68);
        j["fit_landmark_error_px"] = sum / 68;
      }
      auto target = make_fit_target(*cap, fit_points, noiseless_depth);
      if (target && setup.dlib_fit && setup.embedding)
        target->landmark_vertices = setup.embedding->for_expression(ge.name);
      if (!target) {
        auto stop = failed("landmarks", target.error());
        if (!stop) return stop.failure();
        if (*stop) break;
        continue;
      }
      j["fused_frames"] = cap->fused_frames;
      j["dropped_frames"] = cap->dropped_frames;
      j["face_box"] = {{"source", cap->box_source},
                       {"x", cap->box.x},
                       {"y", cap->box.y},
                       {"width", cap->box.width},
                       {"height", cap->box.height}};
      if (!cap->box_note.empty()) j["face_box"]["note"] = cap->box_note;
      frames_fused += cap->fused_frames;
      frames_dropped += cap->dropped_frames;
      boxes_detected += cap->box_source == "dlib";
      {  // how well the colour -> depth lifting puts the points (vs the true depth-image points)
        double sum = 0;
        int n = 0;
        for (int l = 0; l < 68; ++l)
          if (target->landmarks[static_cast<std::size_t>(l)].valid) {
            sum += (target->landmarks[static_cast<std::size_t>(l)].pixel -
                    cap->truth_depth_px[static_cast<std::size_t>(l)])
                       .norm();
            ++n;
          }
        j["lifted_landmark_error_px"] = n ? sum / n : NAN;
        lift_err.add(n ? sum / n : NAN);
      }
      if (e == 0) {
        auto fit = fit_neutral(*model, *target, {}, nullptr, &*model_system);
        if (!fit) {
          auto stop = failed("neutral fit", fit.error());
          if (!stop) return stop.failure();
          break;
        }
        neutral = std::move(*fit);
        qa_passed += fit_passes_qa(neutral, *target);
        append_vertex_distances(neutral.vertices, neutral.camera_from_model, cap->truth_mesh,
                                cap->truth_pose, eye_mouth, eye_mouth_err);
        const double vi =
            mean_vertex_distance(neutral.initial_vertices, neutral.camera_from_model,
                                 cap->truth_mesh, cap->truth_pose, model->fitting_vertices);
        const double vr =
            mean_vertex_distance(neutral.vertices, neutral.camera_from_model, cap->truth_mesh,
                                 cap->truth_pose, model->fitting_vertices);
        rms_init.add(neutral.rms_to_depth_mm_initial);
        rms_ref.add(neutral.rms_to_depth_mm);
        ne_init.add(vi);
        ne_ref.add(vr);
        neutral_ms.add(neutral.times.total_ms());
        j["rms_to_depth_mm_initial"] = neutral.rms_to_depth_mm_initial;
        j["rms_to_depth_mm"] = neutral.rms_to_depth_mm;
        j["vertex_error_mm_initial"] = vi;
        j["vertex_error_mm"] = vr;
        const VertexErrorParts parts =
            vertex_error_parts(neutral.vertices, neutral.camera_from_model, cap->truth_mesh,
                               cap->truth_pose, model->fitting_vertices, model->triangles);
        j["vertex_error_parts"] = vertex_error_json(parts);
        std::fprintf(stderr,
                     "  neutral: offset %.2f %.2f %.2f mm; error less the offset %.2f mm, less "
                     "a rigid motion %.2f mm (%.2f deg); along the normal %.2f, across %.2f mm\n",
                     parts.mean_offset_mm.x(), parts.mean_offset_mm.y(), parts.mean_offset_mm.z(),
                     parts.after_translation_mm, parts.after_rigid_mm, parts.rigid_rotation_deg,
                     parts.normal_mm, parts.tangential_mm);
        j["fit_ms"] = neutral.times.total_ms();
        j["fit_rounds"] = neutral.rounds;
        std::fprintf(stderr,
                     "  neutral: RMS to depth %s -> %s mm, vertex error %s -> %s mm, %.0f ms\n",
                     figure_text(neutral.rms_to_depth_mm_initial, 3).c_str(),
                     figure_text(neutral.rms_to_depth_mm, 3).c_str(), figure_text(vi, 3).c_str(),
                     figure_text(vr, 3).c_str(), neutral.times.total_ms());
        // Robustness: the same capture with stronger landmark noise.
        if (*robust_noise > 0) {
          auto t2 = make_fit_target(*cap, noisy(cap->truth_color_px, *robust_noise, rng),
                                    noiseless_depth);
          if (!t2) return t2.failure();
          auto f2 = fit_neutral(*model, *t2, {}, nullptr, &*model_system);
          if (!f2) return f2.failure();
          const double vn =
              mean_vertex_distance(f2->vertices, f2->camera_from_model, cap->truth_mesh,
                                   cap->truth_pose, model->fitting_vertices);
          ne_noise.add(vn);
          j["vertex_error_mm_robustness_noise"] = vn;
        }
        g0.resize(static_cast<std::size_t>(model->vertex_count) * 3);
        model->evaluate({}, {}, g0);
        auto tr = ExpressionTransfer::create(*model, neutral.vertices, g0);
        if (!tr) return tr.failure();
        transfer.emplace(std::move(*tr));
        // dlib on the untextured render.
        if (detector) {
          ++detection_attempts;
          detector->reset_tracking();
          const auto t0 = Clock::now();
          auto found = detector->detect(cap->color);
          lm_ms_full.add(ms_since(t0));
          if (found) {
            ++detections;
            double sum = 0, sum_in = 0;
            for (int i = 0; i < 68; ++i) {
              const double d = (found->points[static_cast<std::size_t>(i)] -
                                cap->truth_color_px[static_cast<std::size_t>(i)])
                                   .norm();
              sum += d;
              if (i >= 17) sum_in += d;
            }
            lm_err.add(sum / 68);
            lm_err_interior.add(sum_in / 51);
            j["dlib_landmark_error_px"] = sum / 68;
            // Tracking cost over the take.
            for (std::size_t f = 1; f < cap->colors.size(); ++f) {
              const auto t1 = Clock::now();
              auto tracked = detector->detect(cap->colors[f]);
              if (tracked && tracked->tracked) lm_ms_track.add(ms_since(t1));
            }
          }
        }
        if (s == 0) {
          const std::filesystem::path png = options.get("png");
          if (!png.empty() && !cap->confidence.empty()) {
            // The depth confidence the fit weighted its depth term with (white = 1).
            cv::Mat conf(cap->confidence.height, cap->confidence.width, CV_8UC1);
            for (int y = 0; y < conf.rows; ++y)
              for (int x = 0; x < conf.cols; ++x)
                conf.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>(
                    std::lround(255.0f * std::clamp(cap->confidence.at(x, y), 0.0f, 1.0f)));
            std::filesystem::path cpng = png;
            cpng.replace_extension(".confidence.png");
            if (auto ok = write_png(cpng, conf); !ok) return ok.failure();
          }
          if (!png.empty()) {
            cv::Mat a =
                error_panel(*model, neutral.initial_vertices, neutral.camera_from_model, *cap,
                            cap->box, scale, "initial (PCA)", neutral.rms_to_depth_mm_initial);
            cv::Mat b = error_panel(*model, neutral.vertices, neutral.camera_from_model, *cap,
                                    cap->box, scale, "refined", neutral.rms_to_depth_mm);
            cv::Mat row;
            cv::hconcat(
                std::vector<cv::Mat>{a, cv::Mat(a.rows, 10, CV_8UC3, cv::Scalar(255, 255, 255)), b},
                row);
            if (auto ok = write_png(png, row); !ok) return ok.failure();
          }
        }
      } else {
        auto gi = guide_mesh(ge, *model);
        if (!gi) return gi.failure();
        auto fit = fit_expression(*model, *transfer, *gi, *target);
        if (!fit) {
          auto stop = failed("expression fit", fit.error());
          if (!stop) return stop.failure();
          continue;
        }
        qa_passed += fit_passes_qa(*fit, *target);
        append_vertex_distances(fit->vertices, fit->camera_from_model, cap->truth_mesh,
                                cap->truth_pose, eye_mouth, eye_mouth_err);
        const double vi =
            mean_vertex_distance(fit->initial_vertices, fit->camera_from_model, cap->truth_mesh,
                                 cap->truth_pose, model->fitting_vertices);
        const double vr =
            mean_vertex_distance(fit->vertices, fit->camera_from_model, cap->truth_mesh,
                                 cap->truth_pose, model->fitting_vertices);
        ee_init.add(vi);
        ee_ref.add(vr);
        erms_ref.add(fit->rms_to_depth_mm);
        expr_ms.add(fit->times.total_ms());
        expr_err[e].add(vr);
        j["rms_to_depth_mm_initial"] = fit->rms_to_depth_mm_initial;
        j["rms_to_depth_mm"] = fit->rms_to_depth_mm;
        j["vertex_error_mm_initial"] = vi;
        j["vertex_error_mm"] = vr;
        j["fit_ms"] = fit->times.total_ms();
        std::fprintf(stderr, "  %s: RMS to depth %s -> %s mm, vertex error %s -> %s mm, %.0f ms\n",
                     ge.name.c_str(), figure_text(fit->rms_to_depth_mm_initial, 3).c_str(),
                     figure_text(fit->rms_to_depth_mm, 3).c_str(), figure_text(vi, 3).c_str(),
                     figure_text(vr, 3).c_str(), fit->times.total_ms());
      }
      exprs.push_back(j);
    }
    subject["captures"] = exprs;
    per_subject.push_back(subject);
  }
  for (const auto& [e, st] : expr_err)
    per_expression[guide->expressions[static_cast<std::size_t>(e)].name] = st.mean();

  nlohmann::json out;
  out["identities"] = *identities;
  out["world"] = world.empty() ? "plain synthetic camera" : world;
  out["captures"] = captures;
  out["captures_failed"] = captures_failed;
  out["capture_failures_by_stage"] = failure_reasons;
  // Fusion: frames fused and frames it could not follow (dropped, not fused) over the captures
  // that got that far; the face box from dlib on frame 0 or the fixed rectangle.
  out["fused_frames"] = frames_fused;
  out["dropped_frames"] = frames_dropped;
  out["face_boxes_detected"] = boxes_detected;
  out["fit_landmark_source"] =
      setup.dlib_fit ? "dlib on the colour image of frame 0 (what runs on real frames)"
                     : "ground-truth colour-image landmarks + Gaussian noise";
  if (setup.dlib_fit) {
    out["fit_landmark_error_px"] =
        fit_dlib_err.empty() ? nlohmann::json(nullptr) : nlohmann::json(fit_dlib_err.mean());
    out["fit_landmark_detections"] =
        std::to_string(fit_dlib_found) + "/" + std::to_string(fit_dlib_attempts);
    out["fit_landmark_error_by_group"] =
        landmark_group_errors(dlib_bias_sum, dlib_len_sum, fit_dlib_found);
  }
  out["expressions"] = expressions->size();
  out["frames_per_capture"] = *frames;
  out["landmark_source"] =
      setup.dlib_fit
          ? "dlib's points on the colour image of frame 0, lifted into the depth camera through "
            "the registration the camera reports and the fused depth"
          : "ground-truth colour-image landmarks (projected model landmark vertices) + Gaussian "
            "noise of landmark_noise_px per axis, lifted into the depth camera through the "
            "registration and the fused depth; dlib is scored separately (landmark_error_px)";
  out["landmark_noise_px"] = *noise;
  out["lifted_landmark_error_px"] = lift_err.mean();
  out["depth_used"] =
      noiseless_depth ? "noiseless rendering (diagnostic, not the figure)" : "fused";
  out["depth_source"] =
      "KinectFusion (algo/fusion) over the synthetic head-turn take, ray-cast at frame 0";
  out["vertex_error_region"] =
      "the model's fitting vertices (7801 face vertices), camera frame, vs ground truth";
  out["rms_definition"] =
      "point-to-plane distance of fitting vertices to the fused depth (10 mm gate)";
  out["neutral_rms_to_depth_mm_initial"] = rms_init.mean();
  out["neutral_rms_to_depth_mm"] = rms_ref.mean();
  out["neutral_rms_to_depth_mm_worst"] = rms_ref.max();
  out["neutral_vertex_error_mm_initial"] = ne_init.mean();
  out["neutral_vertex_error_mm"] = ne_ref.mean();
  out["neutral_vertex_error_mm_worst"] = ne_ref.max();
  if (!ne_noise.empty()) {
    out["robustness_noise_px"] = *robust_noise;
    out["neutral_vertex_error_mm_with_robustness_noise"] = ne_noise.mean();
  }
  if (!ee_ref.empty()) {
    out["expression_vertex_error_mm_initial"] = ee_init.mean();
    out["expression_vertex_error_mm"] = ee_ref.mean();
    out["expression_vertex_error_mm_worst"] = ee_ref.max();
    out["expression_rms_to_depth_mm"] = erms_ref.mean();
    out["expression_vertex_error_mm_by_expression"] = per_expression;
    out["expression_fit_ms_mean"] = expr_ms.mean();
  }
  out["neutral_fit_ms_mean"] = neutral_ms.mean();
  // Over every fitted capture, neutral and expressions: the tail shows a mesh pulled into
  // holes or depth jumps at the eyes and mouth, which the mean hides.
  out["eye_mouth_vertex_error_mm_p99"] = eye_mouth_err.empty()
                                             ? nlohmann::json(nullptr)
                                             : nlohmann::json(percentile(eye_mouth_err, 0.99));
  out["eye_mouth_vertex_error_mm_mean"] =
      eye_mouth_err.empty()
          ? nlohmann::json(nullptr)
          : nlohmann::json(std::accumulate(eye_mouth_err.begin(), eye_mouth_err.end(), 0.0) /
                           static_cast<double>(eye_mouth_err.size()));
  out["eye_mouth_region"] = "fitting vertices within 10 mm of an eye or mouth landmark vertex (" +
                            std::to_string(eye_mouth.size()) + " vertices)";
  // The device's QA rule (algo/fitting/fit_qa.hpp defaults); a capture that failed before its
  // fit fails QA too.
  out["qa_passed"] = std::to_string(qa_passed) + "/" + std::to_string(captures);
  out["qa_passed_fraction"] = captures > 0
                                  ? nlohmann::json(static_cast<double>(qa_passed) / captures)
                                  : nlohmann::json(nullptr);
  if (detector) {
    out["landmark_error_px"] = lm_err.mean();
    out["landmark_error_px_interior"] = lm_err_interior.mean();
    out["landmark_detections"] =
        std::to_string(detections) + "/" + std::to_string(detection_attempts);
    out["landmark_error_note"] =
        "dlib HOG + shape_predictor_68 on the synthetic colour render (frame 0 of each neutral "
        "take; textured only in a world with texture) vs the projected model landmark vertices; "
        "dlib's annotation convention differs from the model's landmark vertices";
    out["landmark_ms_full_image"] = lm_ms_full.mean();
    out["landmark_ms_tracked"] = lm_ms_track.mean();
  } else {
    out["landmark_error_px"] = nullptr;
  }
  if (!options.get("png").empty())
    out["error_map_png"] = std::filesystem::absolute(options.get("png")).string();
  nlohmann::json targets = {{"neutral_rms_to_depth_mm", 0.3},
                            {"neutral_vertex_error_mm", 1.0},
                            {"expression_vertex_error_mm", 1.5}};
  out["targets"] = targets;
  out["meets_targets"] =
      rms_ref.mean() <= 0.3 && ne_ref.mean() <= 1.0 && (ee_ref.empty() || ee_ref.mean() <= 1.5);
  out["per_subject"] = per_subject;
  return out;
}

int run_eval_fit(const ParsedOptions& options) {
  auto identities = options.get_int("identities");
  if (!identities) return report_failure(identities.error());
  auto first_seed = options.get_int("first-seed");
  if (!first_seed) return report_failure(first_seed.error());
  auto frames = options.get_int("frames");
  if (!frames) return report_failure(frames.error());
  auto noise = options.get_double("landmark-noise-px");
  if (!noise) return report_failure(noise.error());
  auto robust_noise = options.get_double("robustness-noise-px");
  if (!robust_noise) return report_failure(robust_noise.error());
  if (*identities < 1 || *frames < 2 || *noise < 0)
    return report_failure({"--identities >= 1, --frames >= 2 and --landmark-noise-px >= 0"});
  auto model = load_face_model();
  if (!model) return report_failure(model.error());
  auto guide = load_guide(*model, options.get("guide"));
  if (!guide) return report_failure(guide.error());
  auto model_system = model_refine_system(*model);
  if (!model_system) return report_failure(model_system.error());
  const bool noiseless_depth = options.get("depth") == "noiseless";  // diagnostics only
  auto expressions = parse_expression_list(options.get("expressions"), *guide);
  if (!expressions) return report_failure(expressions.error());
  const std::string scenario = options.get("scenario");
  const std::string fit_landmarks = options.get("fit-landmarks").empty()
                                        ? (scenario.empty() ? "truth" : "dlib")
                                        : options.get("fit-landmarks");
  if (fit_landmarks != "truth" && fit_landmarks != "dlib")
    return report_failure({"--fit-landmarks must be truth or dlib"});
  if (fit_landmarks == "dlib" && options.get("dlib") == "off")
    return report_failure({"--fit-landmarks dlib needs dlib: drop --dlib off"});
  std::vector<std::string> parts;
  if (!scenario.empty()) {
    SyntheticOptions probe;
    if (auto ok = apply_world_preset(scenario, 1, probe); !ok) return report_failure(ok.error());
    if (scenario == "realistic") {
      parts = {"baseline"};
      for (const auto& p : world_parts()) parts.push_back(p);
    }
    parts.push_back(scenario);
  }
  std::optional<LandmarkDetector> detector;
  if (options.get("dlib") != "off") {
    std::cerr << "eval fit: loading the dlib landmark model...\n";
    auto d = load_detector(options.get("shape-predictor"));
    if (!d) return report_failure(d.error());
    detector.emplace(std::move(*d));
  }
  FitEvalSetup setup;
  setup.model = &*model;
  setup.guide = &*guide;
  setup.model_system = &*model_system;
  setup.detector = detector ? &*detector : nullptr;
  setup.expressions = *expressions;
  setup.identities = *identities;
  setup.first_seed = *first_seed;
  setup.frames = *frames;
  setup.noise = *noise;
  setup.robust_noise = *robust_noise;
  setup.noiseless_depth = noiseless_depth;
  setup.dlib_fit = fit_landmarks == "dlib";
  if (const std::string e = options.get("landmark-embedding"); e != "model") {
    auto embedding = e == "dlib" ? load_landmark_embedding(*model)
                                 : load_landmark_embedding(*model, std::filesystem::path(e));
    if (!embedding) return report_failure(embedding.error());
    setup.embedding = *embedding;
  }
  auto unit_calibration = parse_unit_calibration(options.get("unit-calibration"));
  if (!unit_calibration) return report_failure(unit_calibration.error());
  setup.unit_calibration = *unit_calibration;
  if (parts.empty()) {
    auto out = eval_fit_once(options, setup, "");
    if (!out) return report_failure(out.error());
    std::cout << out->dump(2) << std::endl;
    return kExitOk;
  }
  // Each part alone (and, for realistic, the plain world with the same landmarks as a
  // baseline), then the scenario itself: its figures are the top level.
  nlohmann::json scenarios;
  nlohmann::json out;
  for (const auto& part : parts) {
    std::cerr << "eval fit: scenario " << part << "\n";
    auto run = eval_fit_once(options, setup, part == "baseline" ? "none" : part);
    if (!run) return report_failure(run.error());
    if (decalibrates_unit(part) && setup.unit_calibration == UnitCalibration::kSelfCalibrated) {
      // The same run with the depth law known (registration self-calibrated), and on the unit
      // calibrated perfectly: the reference self-calibration is held to.
      nlohmann::json ratio;
      for (const auto mode : {UnitCalibration::kSelfWithDepthLaw, UnitCalibration::kCalibrated}) {
        std::cerr << "eval fit: scenario " << part << ", unit " << unit_calibration_name(mode)
                  << "\n";
        FitEvalSetup other = setup;
        other.unit_calibration = mode;
        auto c = eval_fit_once(options, other, part);
        if (!c) return report_failure(c.error());
        c->erase("per_subject");
        (*run)[std::string("unit_") + unit_calibration_name(mode)] = std::move(*c);
      }
      const auto& reference = (*run)["unit_calibrated"];
      for (const auto& [name, figures] :
           {std::pair<std::string, const nlohmann::json*>{"self", &*run},
            {"self-depth-law", &(*run)["unit_self-depth-law"]}})
        ratio[name] = {
            {"neutral_vertex_error_mm",
             ratio_of((*figures)["neutral_vertex_error_mm"], reference["neutral_vertex_error_mm"])},
            {"expression_vertex_error_mm", ratio_of((*figures)["expression_vertex_error_mm"],
                                                    reference["expression_vertex_error_mm"])}};
      (*run)["decalibrated_vs_calibrated_ratio"] = ratio;
    }
    if (part == scenario) out = *run;
    run->erase("per_subject");
    scenarios[part] = std::move(*run);
  }
  out["scenario"] = scenario;
  out["scenarios"] = scenarios;
  out["unit_calibration"] = unit_calibration_name(setup.unit_calibration);
  std::cout << out.dump(2) << std::endl;
  return kExitOk;
}

// ---------------------------------------------------------------------------------------------
// facebooth-lab bench fit

int run_bench_fit(const ParsedOptions& options) {
  auto seed = options.get_int("seed");
  if (!seed) return report_failure(seed.error());
  auto repeats = options.get_int("repeats");
  if (!repeats || *repeats < 1) return report_failure({"--repeats must be at least 1"});
  auto model = load_face_model();
  if (!model) return report_failure(model.error());
  auto guide = load_guide(*model, options.get("guide"));
  if (!guide) return report_failure(guide.error());
  const std::vector<float> identity =
      identity_draw(static_cast<std::uint64_t>(*seed), model->identity_count);
  nlohmann::json out;
  std::cerr << "bench fit: captures (synthetic + fusion)...\n";
  auto neutral_cap = capture(*model, identity, {}, 1, 30, true);
  if (!neutral_cap) return report_failure(neutral_cap.error());
  // Landmarks: full-image detection once, then tracked frames.
  if (options.get("dlib") != "off") {
    auto det = load_detector(options.get("shape-predictor"));
    if (!det) return report_failure(det.error());
    Samples full, tracked;
    for (long long r = 0; r < *repeats; ++r) {
      det->reset_tracking();
      const auto t0 = Clock::now();
      auto f = det->detect(neutral_cap->colors.front());
      full.add(ms_since(t0));
      if (!f) return report_failure(f.error());
      for (std::size_t i = 1; i < neutral_cap->colors.size(); ++i) {
        const auto t1 = Clock::now();
        auto t = det->detect(neutral_cap->colors[i]);
        if (t && t->tracked) tracked.add(ms_since(t1));
      }
    }
    out["landmark_ms"] = tracked.mean();
    out["landmark_ms_full_image"] = full.mean();
    out["landmark_tracked_frames"] = tracked.size();
  }
  auto target = make_fit_target(*neutral_cap, neutral_cap->truth_color_px, false);
  if (!target) return report_failure(target.error());
  double best_neutral = 1e30, best_step1 = 0, best_refine = 0;
  // Once per model (the daemon would do it at start): the mean face's refinement matrix.
  const auto ms0 = Clock::now();
  auto model_system = model_refine_system(*model);
  if (!model_system) return report_failure(model_system.error());
  out["model_refine_factorization_ms"] = ms_since(ms0);
  FitResult neutral;
  for (long long r = 0; r < *repeats; ++r) {
    auto fit = fit_neutral(*model, *target, {}, nullptr, &*model_system);
    if (!fit) return report_failure(fit.error());
    if (fit->times.total_ms() < best_neutral) {
      best_neutral = fit->times.total_ms();
      best_step1 = fit->times.initial_ms;
      best_refine = fit->times.refine_ms;
    }
    neutral = std::move(*fit);
  }
  out["neutral_fit_ms"] = best_neutral;
  out["neutral_step1_ms"] = best_step1;
  out["neutral_refine_ms"] = best_refine;
  std::vector<float> g0(static_cast<std::size_t>(model->vertex_count) * 3);
  model->evaluate({}, {}, g0);
  const auto tf0 = Clock::now();
  auto transfer = ExpressionTransfer::create(*model, neutral.vertices, g0);
  if (!transfer) return report_failure(transfer.error());
  const double subject_setup_ms = ms_since(tf0);
  out["transfer_factorization_ms"] = subject_setup_ms;
  out["refine_factorization_ms"] = transfer->refine_system().factorization_ms();
  Samples expr, dt;
  const int n_expr = static_cast<int>(std::min<long long>(guide->expressions.size(), 4));
  for (int e = 1; e < n_expr; ++e) {
    auto w = guide_weights(guide->expressions[static_cast<std::size_t>(e)], *model);
    auto gi = guide_mesh(guide->expressions[static_cast<std::size_t>(e)], *model);
    auto cap = capture(*model, identity, *w, 100 + e, 30, false);
    if (!cap) return report_failure(cap.error());
    auto t = make_fit_target(*cap, cap->truth_color_px, false);
    if (!t) return report_failure(t.error());
    double best = 1e30;
    for (long long r = 0; r < *repeats; ++r) {
      const auto t1 = Clock::now();
      auto s = transfer->transfer(*gi);
      dt.add(ms_since(t1));
      auto fit = fit_expression(*model, *transfer, *gi, *t);
      if (!fit) return report_failure(fit.error());
      best = std::min(best, fit->times.total_ms());
    }
    expr.add(best);
  }
  out["expression_fit_ms"] = expr.mean();
  // The subject's two factorizations happen once for its 19 expressions.
  out["expression_fit_ms_with_setup_share"] = expr.mean() + subject_setup_ms / 19.0;
  out["deformation_transfer_ms"] = dt.mean();
  out["definition"] =
      "wall clock on one thread, best of --repeats; neutral = PCA fit + refinement with the "
      "model's refinement matrix (model_refine_factorization_ms, once per model); expression = "
      "transfer + rigid alignment + refinement with the subject's "
      "shared refinement matrix; transfer_factorization_ms = ExpressionTransfer::create, once "
      "per subject: the transfer's and the refinement's factorization (refine_factorization_ms) "
      "of the fitted neutral; expression_fit_ms_with_setup_share adds 1/19 of it; landmark_ms = "
      "tracked frames (detector on the face window + shape predictor)";
  out["targets"] = {{"landmark_ms", 5}, {"neutral_fit_ms", 300}, {"expression_fit_ms", 150}};
  std::cout << out.dump(2) << std::endl;
  return kExitOk;
}

// ---------------------------------------------------------------------------------------------
// facebooth guide thumbnails

}  // namespace

std::vector<Command> fit_commands() {
  const OptionSpec guide_opt{"guide", "FILE",
                             "guide recipes (default: DATA_DIR/guide_expressions.json)", ""};
  const OptionSpec predictor_opt{"shape-predictor", "FILE",
                                 "dlib 68-point model (.dat or .dat.bz2)", kShapePredictorDefault};
  const OptionSpec json_opt{"json", "",
                            "print JSON (the only output format; accepted for symmetry)", ""};
  return {
      {{"eval fit",
        "score landmarks + neutral/expression fitting on synthetic subjects (JSON on stdout)",
        "Each capture: synthetic head-turn take with sensor noise -> KinectFusion -> fused frontal "
        "depth; landmarks are the true colour-image points plus Gaussian noise (dlib is scored "
        "separately on the same renders). The full figure run is --identities 5 (all 20 "
        "expressions).",
        {{"identities", "N", "synthetic subjects (random identity each)", "5"},
         {"first-seed", "N", "seed of the first subject", "1"},
         {"expressions", "LIST", "all, or comma-separated names/ids (neutral always runs)", "all"},
         {"frames", "N", "frames per head-turn take fused", "45"},
         {"landmark-noise-px", "PX", "Gaussian noise on the true landmarks (per axis)", "1"},
         {"robustness-noise-px", "PX", "extra neutral fit with this landmark noise (0 = skip)",
          "5"},
         {"png", "FILE", "error map of the first neutral fit (initial | refined)", ""},
         {"dlib", "on|off", "score dlib's landmarks on the renders", "on"},
         {"scenario", "NAME",
          "realistic (every part alone, a baseline, then all together; JSON scenarios.<part>) or "
          "one part: identity|texture|hair|clutter|noise|unit (sim/camera/"
          "world_presets.hpp); empty = the plain synthetic camera",
          ""},
         {"unit-calibration", "self|self-depth-law|reported|calibrated", kUnitCalibrationHelp,
          "self"},
         {"fit-landmarks", "dlib|truth",
          "the fit's landmarks: dlib on frame 0's colour image, or truth + --landmark-noise-px "
          "(default: dlib with --scenario, truth without)",
          ""},
         {"depth", "fused|noiseless",
          "fit the fused depth (the figure) or, to isolate fusion "
          "error, the noiseless rendering",
          "fused"},
         {"landmark-embedding", "dlib|model|FILE",
          "the mesh vertices dlib's points mark in the fit: dlib = DATA_DIR/"
          "dlib_landmark_embedding.csv (as the product), model = the model's own landmark "
          "vertices, or a file from `landmarks embed`",
          "dlib"},
         predictor_opt,
         guide_opt,
         json_opt}},
       run_eval_fit},
      {{"bench fit",
        "time landmarks, neutral fit and expression fits (JSON on stdout)",
        "",
        {{"seed", "N", "synthetic subject", "1"},
         {"repeats", "N", "best of N", "3"},
         {"dlib", "on|off", "time the dlib landmark tracker", "on"},
         predictor_opt,
         guide_opt,
         json_opt}},
       run_bench_fit},
  };
}

}  // namespace fb::cli
