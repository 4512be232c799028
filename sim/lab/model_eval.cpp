// facebooth-lab eval model: the bilinear model (algo/bilinear, FaceWarehouse 3.3 and 4.1-4.4)
// scored on synthetic subjects: held-out reconstruction against the knob counts, and landmark
// fits on held-out synthetic images. JSON on stdout, progress on stderr.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include "algo/bilinear/bootstrap.hpp"
#include "algo/bilinear/image_fit.hpp"
#include "algo/core/clock.hpp"
#include "algo/fitting/expression_transfer.hpp"
#include "algo/rigging/example_rigging.hpp"
#include "host/cli/frame_png.hpp"
#include "host/cli/guide_files.hpp"
#include "host/cli/progress.hpp"
#include "host/cli/rig_session.hpp"
#include "host/cli/rig_support.hpp"
#include "host/cli/stats.hpp"
#include "sim/camera/synthetic_camera.hpp"
#include "sim/lab/lab_commands.hpp"
#include "sim/subject/synthetic_capture.hpp"
#include "storage/asset_files.hpp"
#include "storage/durable_file.hpp"

#include "sim/lab/rig_eval.hpp"

namespace fb::cli {
namespace {

struct KnobCell {
  int id_knobs = 0, exp_knobs = 0;
  double error_mm = 0;
};

// Held-out reconstruction in the factored tensor's coefficient space: for subject s with true
// slices basis * a(s, e), w_id minimises sum_e |basis_f (M_e w - a(s, e))|^2 over the fitting
// vertices (Gram G), M_e = sum_b U~_exp[e, b] Ccoef_b; the error is the mean vertex distance of
// basis (M_e w - a(s, e)) over `error_rows` (a vertex subset), averaged over e and subjects.
double heldout_error(const FactoredTensor& train, const ModeFactors& factors,
                     const Eigen::MatrixXd& gram, const Eigen::MatrixXd& error_basis,
                     const std::vector<std::vector<float>>& heldout_ids, int id_knobs,
                     int exp_knobs) {
  const Eigen::MatrixXd u_exp = factors.expression.leftCols(exp_knobs);
  const Eigen::MatrixXd ccoef =
      factored_core(train, factors.identity.leftCols(id_knobs), u_exp);  // K x (b * a)
  const Eigen::MatrixXd g_ccoef = gram * ccoef;
  const Eigen::Index k = ccoef.rows();
  const int n_exp = train.expressions;
  const int n_modes = static_cast<int>(heldout_ids.front().size());
  std::vector<Eigen::MatrixXd> m(static_cast<std::size_t>(n_exp)), gm(m.size());
  for (int e = 0; e < n_exp; ++e) {
    m[e] = Eigen::MatrixXd::Zero(k, id_knobs);
    gm[e] = Eigen::MatrixXd::Zero(k, id_knobs);
    for (int b = 0; b < exp_knobs; ++b) {
      m[e] += u_exp(e, b) * ccoef.middleCols(static_cast<Eigen::Index>(b) * id_knobs, id_knobs);
      gm[e] += u_exp(e, b) * g_ccoef.middleCols(static_cast<Eigen::Index>(b) * id_knobs, id_knobs);
    }
  }
  Eigen::MatrixXd h = Eigen::MatrixXd::Zero(id_knobs, id_knobs);
  for (int e = 0; e < n_exp; ++e) h.noalias() += m[e].transpose() * gm[e];
  h.diagonal().array() += 1e-9 * h.diagonal().mean();
  const Eigen::LDLT<Eigen::MatrixXd> solver(h);
  const Eigen::Index rows = error_basis.rows() / 3;
  double total = 0;
  for (const auto& c : heldout_ids) {
    Eigen::MatrixXd a = Eigen::MatrixXd::Zero(k, n_exp);
    for (int e = 0; e < n_exp; ++e) {
      a(0, e) = 1.0;
      for (int q = 0; q < n_modes; ++q) a(1 + q, e) = c[static_cast<std::size_t>(q)];
      if (e > 0) a(n_modes + e, e) = 1.0;
    }
    Eigen::VectorXd g = Eigen::VectorXd::Zero(id_knobs);
    for (int e = 0; e < n_exp; ++e) g.noalias() += gm[e].transpose() * a.col(e);
    const Eigen::VectorXd w = solver.solve(g);
    Eigen::MatrixXd residual(k, n_exp);
    for (int e = 0; e < n_exp; ++e) residual.col(e) = m[e] * w - a.col(e);
    const Eigen::MatrixXd d = error_basis * residual;  // (3 rows) x E
    double s = 0;
    for (int e = 0; e < n_exp; ++e)
      for (Eigen::Index v = 0; v < rows; ++v) s += d.block<3, 1>(3 * v, e).norm();
    total += s / (static_cast<double>(rows) * n_exp);
  }
  return total / static_cast<double>(heldout_ids.size());
}

Eigen::MatrixXd basis_rows(const FactoredTensor& t, std::span<const std::uint32_t> vertices,
                           int stride) {
  std::vector<std::uint32_t> use;
  for (std::size_t i = 0; i < vertices.size(); i += static_cast<std::size_t>(stride))
    use.push_back(vertices[i]);
  Eigen::MatrixXd out(3 * static_cast<Eigen::Index>(use.size()), t.basis.cols());
  for (std::size_t i = 0; i < use.size(); ++i)
    out.middleRows(3 * static_cast<Eigen::Index>(i), 3) =
        t.basis.middleRows(3 * static_cast<Eigen::Index>(use[i]), 3).cast<double>();
  return out;
}

Result<void> write_knob_plot(const std::filesystem::path& path, const std::vector<KnobCell>& cells,
                             const std::vector<int>& id_list, const std::vector<int>& exp_list,
                             int identities, int heldout) {
  const int w = 900, h = 600, left = 80, right = 190, top = 60, bottom = 70;
  cv::Mat img(h, w, CV_8UC3, cv::Scalar(255, 255, 255));
  double ymax = 0;
  for (const auto& c : cells) ymax = std::max(ymax, c.error_mm);
  ymax = std::max(0.5, std::ceil(ymax * 2) / 2);
  const double xmax = *std::max_element(id_list.begin(), id_list.end());
  auto px = [&](double x, double y) {
    return cv::Point(left + static_cast<int>(x / xmax * (w - left - right)),
                     h - bottom - static_cast<int>(y / ymax * (h - top - bottom)));
  };
  const cv::Scalar black(0, 0, 0), grey(210, 210, 210);
  for (int k = 0; k <= 10; ++k) {
    const double y = ymax * k / 10;
    cv::line(img, px(0, y), px(xmax, y), grey, 1);
    char t[32];
    std::snprintf(t, sizeof t, "%.2f", y);
    cv::putText(img, t, px(0, y) + cv::Point(-58, 5), cv::FONT_HERSHEY_SIMPLEX, 0.45, black, 1,
                cv::LINE_AA);
  }
  for (int x : id_list) {
    cv::line(img, px(x, 0), px(x, 0) + cv::Point(0, 6), black, 1);
    cv::putText(img, std::to_string(x), px(x, 0) + cv::Point(-10, 24), cv::FONT_HERSHEY_SIMPLEX,
                0.45, black, 1, cv::LINE_AA);
  }
  cv::line(img, px(0, 0), px(xmax, 0), black, 1);
  cv::line(img, px(0, 0), px(0, ymax), black, 1);
  cv::putText(img, "identity knobs", cv::Point(w / 2 - 80, h - 20), cv::FONT_HERSHEY_SIMPLEX, 0.6,
              black, 1, cv::LINE_AA);
  cv::putText(img, "mean vertex error (mm)", cv::Point(10, top - 20), cv::FONT_HERSHEY_SIMPLEX,
              0.55, black, 1, cv::LINE_AA);
  char title[200];
  std::snprintf(title, sizeof title,
                "Held-out reconstruction vs knobs (bootstrap, %d identities, %d held out)",
                identities, heldout);
  cv::putText(img, title, cv::Point(left, 25), cv::FONT_HERSHEY_SIMPLEX, 0.6, black, 1,
              cv::LINE_AA);
  for (std::size_t k = 0; k < exp_list.size(); ++k) {
    cv::Mat hue(1, 1, CV_8UC3, cv::Scalar(static_cast<int>(150.0 * k / exp_list.size()), 220, 200));
    cv::Mat bgr;
    cv::cvtColor(hue, bgr, cv::COLOR_HSV2BGR);
    const cv::Vec3b c = bgr.at<cv::Vec3b>(0, 0);
    const cv::Scalar colour(c[0], c[1], c[2]);
    std::vector<cv::Point> line;
    for (const auto& cell : cells)
      if (cell.exp_knobs == exp_list[k]) line.push_back(px(cell.id_knobs, cell.error_mm));
    cv::polylines(img, line, false, colour, 2, cv::LINE_AA);
    for (const auto& p : line) cv::circle(img, p, 4, colour, cv::FILLED, cv::LINE_AA);
    const cv::Point at(w - right + 20, top + 25 * static_cast<int>(k));
    cv::line(img, at, at + cv::Point(30, 0), colour, 2, cv::LINE_AA);
    cv::putText(img, std::to_string(exp_list[k]) + " exp knobs", at + cv::Point(38, 5),
                cv::FONT_HERSHEY_SIMPLEX, 0.5, black, 1, cv::LINE_AA);
  }
  for (const auto& cell : cells)
    if (cell.id_knobs == 50 && cell.exp_knobs == 25) {
      cv::circle(img, px(50, cell.error_mm), 9, black, 1, cv::LINE_AA);
      cv::putText(img, "default 50 x 25", px(50, cell.error_mm) + cv::Point(12, -10),
                  cv::FONT_HERSHEY_SIMPLEX, 0.45, black, 1, cv::LINE_AA);
    }
  if (auto ok = write_image_file(path, img); !ok) return ok.failure();
  return success();
}

// Similarity-aligned mean distance (weak perspective does not observe absolute size or depth).
double similarity_distance(std::span<const float> a, std::span<const float> b,
                           std::span<const std::uint32_t> subset) {
  Eigen::Matrix3Xd src(3, subset.size()), dst(3, subset.size());
  for (std::size_t i = 0; i < subset.size(); ++i) {
    const auto v = subset[i];
    src.col(static_cast<Eigen::Index>(i)) << a[3 * v], a[3 * v + 1], a[3 * v + 2];
    dst.col(static_cast<Eigen::Index>(i)) << b[3 * v], b[3 * v + 1], b[3 * v + 2];
  }
  const Eigen::Matrix4d t = Eigen::umeyama(src, dst, true);
  const Eigen::Matrix3Xd moved =
      (t.topLeftCorner<3, 3>() * src).colwise() + t.topRightCorner<3, 1>();
  return (moved - dst).colwise().norm().mean();
}

// Landmark fits on held-out synthetic images (the synthetic camera's perspective renders), one
// image at a time and jointly; the figures go into `out`.
Result<void> eval_landmark_fits(const ParsedOptions& options, const FaceModel& face_model,
                                const GuideSet& guide, const FactoredTensor& tensor,
                                const ModeFactors& factors,
                                const std::vector<std::vector<float>>& test_ids, int def_id,
                                int def_exp, long long seed, double noise, long long images,
                                nlohmann::json& out) {
  BilinearModel model;
  if (const std::string file = options.get("model"); !file.empty()) {
    auto bytes = read_file_bytes(file);
    if (!bytes) return bytes.failure();
    auto parsed = parse_bilinear_model(std::as_bytes(std::span(*bytes)));
    if (!parsed) return fail(file + ": " + parsed.error().message);
    if (parsed->vertex_count != face_model.vertex_count)
      return fail(file + ": the model has " + std::to_string(parsed->vertex_count) +
                  " vertices, the face model " + std::to_string(face_model.vertex_count));
    model = std::move(*parsed);
    out["landmark_fit_model"] = std::filesystem::absolute(file).string();
  } else {
    auto built = truncate(tensor, factors, def_id, def_exp);
    if (!built) return built.failure();
    model = make_bilinear_model(*built, face_model, bootstrap_expression_names(face_model), "{}");
    out["landmark_fit_model"] = "bootstrap built in memory at the default knobs";
  }
  Samples fit_px, fit_truth_px, joint_px, mesh_mm, joint_mesh_mm, fit_ms;
  std::mt19937_64 rng(static_cast<std::uint64_t>(seed) * 13 + 5);
  const int per_subject = static_cast<int>(images);
  Progress lbar("eval model: landmark fits", static_cast<long long>(test_ids.size()));
  for (std::size_t s = 0; s < test_ids.size(); ++s) {
    const auto& ge = guide.expressions[1 + s % (guide.expressions.size() - 1)];
    auto w = guide_weights(ge, face_model);
    if (!w) return w.failure();
    SyntheticOptions so;
    so.seed = 500 + s;
    so.identity_coeffs = test_ids[s];
    so.expression_weights = *w;
    so.frame_count = 8 * per_subject;
    auto camera = make_synthetic_camera(face_model, so);
    if (!camera) return camera.failure();
    if (auto ok = (*camera)->start(); !ok) return ok.failure();
    std::vector<ImageLandmarks> shots, truths;
    RgbdFrame frame;
    const auto truth_mesh = face(face_model, test_ids[s], *w);
    for (int f = 0; f < 8 * per_subject; ++f) {
      auto st = (*camera)->next_frame(frame, std::chrono::milliseconds(1000));
      if (!st) return st.failure();
      if (f % 8 != 0) continue;
      const FrameTruth* t = frame_truth(**camera);
      if (!t) return fail("the synthetic camera gave no ground truth");
      ImageLandmarks l, lt;
      const auto noisy_px = noisy(t->landmarks_color_px, noise, rng);
      for (int k = 0; k < 68; ++k) {
        l.points[k] = noisy_px[k];
        lt.points[k] = t->landmarks_color_px[k];
        l.valid[k] = lt.valid[k] = true;
      }
      shots.push_back(l);
      truths.push_back(lt);
    }
    auto score = [&](const LandmarkFit& fit, std::span<const float> w_id, const ImageLandmarks& l,
                     const ImageLandmarks& lt, Samples& given, Samples* vs_truth, Samples& mesh) {
      std::vector<float> mesh_fit(static_cast<std::size_t>(model.coordinate_count()));
      model.evaluate(w_id, fit.w_exp, mesh_fit);
      double sg = 0, st = 0;
      for (int k = 0; k < 68; ++k) {
        const auto v = model.landmark_vertices[k];
        const Eigen::Vector2d p =
            fit.pose.project({mesh_fit[3 * v], mesh_fit[3 * v + 1], mesh_fit[3 * v + 2]});
        sg += (p - l.points[k]).norm();
        st += (p - lt.points[k]).norm();
      }
      given.add(sg / 68);
      if (vs_truth) vs_truth->add(st / 68);
      mesh.add(similarity_distance(mesh_fit, truth_mesh, face_model.fitting_vertices));
    };
    for (std::size_t i = 0; i < shots.size(); ++i) {
      const auto t1 = Clock::now();
      auto fit = fit_landmarks(model, shots[i]);
      fit_ms.add(seconds_since(t1) * 1000);
      if (!fit) return fit.failure();
      score(*fit, fit->w_id, shots[i], truths[i], fit_px, &fit_truth_px, mesh_mm);
    }
    if (shots.size() > 1) {
      auto joint = fit_landmarks_joint(model, shots);
      if (!joint) return joint.failure();
      for (std::size_t i = 0; i < shots.size(); ++i)
        score(joint->images[i], joint->w_id, shots[i], truths[i], joint_px, nullptr, joint_mesh_mm);
    }
    lbar.update(static_cast<long long>(s + 1));
  }
  out["landmark_fit_error_px"] = fit_px.mean();
  out["landmark_fit_error_vs_true_points_px"] = fit_truth_px.mean();
  out["landmark_fit_mesh_error_mm_similarity_aligned"] = mesh_mm.mean();
  out["landmark_fit_ms"] = fit_ms.mean();
  if (!joint_px.empty()) {
    out["joint_fit_images"] = per_subject;
    out["joint_landmark_fit_error_px"] = joint_px.mean();
    out["joint_fit_mesh_error_mm_similarity_aligned"] = joint_mesh_mm.mean();
  }
  out["landmark_fit_definition"] =
      "held-out subjects rendered by the synthetic camera (perspective, head turn; frames 0, 8, "
      "16, ...), one guide expression each; input = the true colour-image landmarks + Gaussian "
      "noise of landmark_noise_px per axis; error = mean distance of the fitted model's projected "
      "landmarks (weak perspective, coordinate descent, default knobs) to the input points; "
      "mesh error after a similarity alignment over the fitting vertices";
  return success();
}

}  // namespace

int run_eval_model(const ParsedOptions& options) {
  auto identities = options.get_int("identities");
  auto heldout = options.get_int("heldout");
  auto seed = options.get_int("seed");
  auto noise = options.get_double("landmark-noise-px");
  auto images = options.get_int("images");
  if (!identities || !heldout || !seed || !noise || !images || *identities < 2 || *heldout < 1 ||
      *images < 1)
    return report_failure({"--identities >= 2, --heldout >= 1, --images >= 1 (integers)"});
  auto face_model = load_face_model();
  if (!face_model) return report_failure(face_model.error());
  auto guide = load_guide(*face_model, options.get("guide"));
  if (!guide) return report_failure(guide.error());
  nlohmann::json out;

  // 1. Reconstruction of held-out subjects vs knob counts (Fig. 4).
  std::cerr << "eval model: decomposing the bootstrap tensor (" << *identities
            << " identities)...\n";
  const auto t0 = Clock::now();
  const auto train_ids = draw_identities(*face_model, static_cast<int>(*identities),
                                         static_cast<std::uint64_t>(*seed));
  const FactoredTensor tensor = bootstrap_tensor(*face_model, train_ids);
  auto factors = mode_factors(tensor);
  if (!factors) return report_failure(factors.error());
  out["decomposition_s"] = seconds_since(t0);
  const auto test_ids = draw_identities(*face_model, static_cast<int>(*heldout),
                                        static_cast<std::uint64_t>(*seed) + 1000003);
  const Eigen::MatrixXd fit_basis = basis_rows(tensor, face_model->fitting_vertices, 1);
  const Eigen::MatrixXd gram = fit_basis.transpose() * fit_basis;
  const Eigen::MatrixXd coarse_basis = basis_rows(tensor, face_model->fitting_vertices, 8);
  std::vector<int> id_list, exp_list;
  for (int a : {5, 10, 20, 30, 50, 75, 100, 150})
    if (a <= tensor.identities) id_list.push_back(a);
  for (int b : {5, 10, 15, 25, 40, 54})
    if (b <= tensor.expressions) exp_list.push_back(b);
  std::vector<KnobCell> cells;
  nlohmann::json table = nlohmann::json::array();
  Progress bar("eval model: knob table", static_cast<long long>(id_list.size() * exp_list.size()));
  for (int b : exp_list)
    for (int a : id_list) {
      const double e = heldout_error(tensor, *factors, gram, coarse_basis, test_ids, a, b);
      cells.push_back({a, b, e});
      table.push_back({{"id_knobs", a}, {"exp_knobs", b}, {"heldout_reconstruction_mm", e}});
      bar.update(static_cast<long long>(cells.size()));
    }
  const int def_id = std::min(50, tensor.identities), def_exp = std::min(25, tensor.expressions);
  out["heldout_reconstruction_mm"] =
      heldout_error(tensor, *factors, gram, fit_basis, test_ids, def_id, def_exp);
  out["default_knobs"] = {def_id, def_exp};
  out["reconstruction_table"] = table;
  out["reconstruction_definition"] =
      "held-out subjects (identities not in the tensor, same 54 expressions): w_id by least "
      "squares over all 54 expressions with w_exp = the model's U_exp rows; mean vertex distance "
      "over the fitting vertices (table: every 8th fitting vertex; headline: all 7801)";
  if (!options.get("plot").empty()) {
    if (auto ok = write_knob_plot(options.get("plot"), cells, id_list, exp_list, tensor.identities,
                                  static_cast<int>(*heldout));
        !ok)
      return report_failure(ok.error());
    out["plot"] = std::filesystem::absolute(options.get("plot")).string();
  }

  // 2. Landmark fit on held-out synthetic images (the synthetic camera's perspective renders).
  if (auto ok = eval_landmark_fits(options, *face_model, *guide, tensor, *factors, test_ids, def_id,
                                   def_exp, *seed, *noise, *images, out);
      !ok)
    return report_failure(ok.error());
  out["landmark_noise_px"] = *noise;
  out["identities"] = *identities;
  out["heldout_subjects"] = *heldout;
  std::cout << out.dump(2) << std::endl;
  return kExitOk;
}

}  // namespace fb::cli
