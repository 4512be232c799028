#include "sim/lab/transfer_image_lab.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>

#include "algo/core/clock.hpp"
#include "algo/core/polygon.hpp"
#include "algo/transfer/image_transfer.hpp"
#include "host/cli/stats.hpp"
#include "sim/camera/synthetic_camera.hpp"
#include "sim/subject/synthetic_photo.hpp"
#include "storage/asset_files.hpp"
#include "storage/durable_file.hpp"
#include "storage/export/png_file.hpp"

namespace fb::cli {

namespace {

// The face the PSNR is scored over: inside the jaw line and the brows raised by a quarter of
// their distance from the landmarks' centroid (the forehead), of the truth's landmarks.
std::vector<bool> face_mask(const FacePhoto& truth) {
  Eigen::Vector2d c = Eigen::Vector2d::Zero();
  for (const auto& p : truth.points) c += p;
  c /= 68.0;
  std::vector<Eigen::Vector2d> poly;
  for (int k = 0; k <= 16; ++k) poly.push_back(truth.points[static_cast<std::size_t>(k)]);
  for (int k = 26; k >= 17; --k)
    poly.push_back(c + (truth.points[static_cast<std::size_t>(k)] - c) * 1.25);
  const int w = truth.image.width, h = truth.image.height;
  std::vector<bool> mask(static_cast<std::size_t>(w) * h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      mask[static_cast<std::size_t>(y) * w + x] = inside_polygon(poly, x, y);
  return mask;
}

// PSNR (dB, 8-bit RGB) over the mask's pixels; 99 when identical.
double psnr(const ColorImage& a, const ColorImage& b, const std::vector<bool>& mask) {
  double se = 0;
  long long n = 0;
  for (std::size_t i = 0; i < a.pixels.size(); ++i) {
    if (!mask.empty() && !mask[i]) continue;
    const double dr = a.pixels[i].r - b.pixels[i].r, dg = a.pixels[i].g - b.pixels[i].g,
                 db = a.pixels[i].b - b.pixels[i].b;
    se += dr * dr + dg * dg + db * db;
    n += 3;
  }
  if (n == 0) return NAN;
  const double mse = se / static_cast<double>(n);
  return mse <= 0 ? 99.0 : 10.0 * std::log10(255.0 * 255.0 / mse);
}

struct PsnrSamples {
  Samples face, image;
  void add(const ColorImage& out, const FacePhoto& truth) {
    face.add(psnr(out, truth.image, face_mask(truth)));
    image.add(psnr(out, truth.image, {}));
  }
  nlohmann::json json() const {
    return {{"face_mean_db", face.mean()},
            {"face_min_db", face.min()},
            {"image_mean_db", image.mean()},
            {"count", face.size()}};
  }
};

}  // namespace

Result<nlohmann::json> image_transfer_eval(const FaceModel& model, int subjects) {
  const auto expressions = photo_expressions(model);
  PsnrSamples self_vtc, cross_vtc, cross_warp, cross_none, cross_additive;
  Samples iterations, residual, ms;
  std::vector<FacePhoto> first;  // subject 1: neutral, then its expressions
  for (int s = 1; s <= subjects; ++s) {
    std::cerr << "eval transfer: photographs of subject " << s << "/" << subjects << "\n";
    PhotoSpec spec;
    spec.subject = static_cast<std::uint64_t>(s);
    auto neutral = render_photo(model, spec);
    if (!neutral) return neutral.failure();
    if (s == 1) first.push_back(*neutral);
    for (std::size_t e = 0; e < expressions.size(); ++e) {
      spec.expression_weights = expressions[e].second;
      auto expr = render_photo(model, spec);
      if (!expr) return expr.failure();
      auto self = transfer_image_expression(*neutral, *expr, *neutral);
      if (!self) return self.failure();
      self_vtc.add(self->image, *expr);
      iterations.add(self->iterations);
      if (s == 1) {
        first.push_back(*expr);
        continue;
      }
      auto cross = transfer_image_expression(first[0], first[e + 1], *neutral);
      if (!cross) return cross.failure();
      cross_vtc.add(cross->image, *expr);
      // The solve's start alone (no iteration): T warped + the source's additive change.
      ImageTransferOptions start;
      start.max_iterations = 0;
      auto additive = transfer_image_expression(first[0], first[e + 1], *neutral, start);
      if (!additive) return additive.failure();
      cross_additive.add(additive->image, *expr);
      cross_warp.add(cross->warped, *expr);
      cross_none.add(neutral->image, *expr);
      iterations.add(cross->iterations);
      residual.add(cross->relative_residual);
      ms.add(cross->warp_ms + cross->solve_ms);
    }
  }
  nlohmann::json out;
  out["image_self_psnr_db"] = self_vtc.face.mean();
  out["image_cross_psnr_db"] = cross_vtc.face.mean();
  out["image_cross_warp_psnr_db"] = cross_warp.face.mean();
  out["image"] = {{"self_vtc", self_vtc.json()},
                  {"cross_vtc", cross_vtc.json()},
                  {"cross_warp_only", cross_warp.json()},
                  {"cross_additive_start", cross_additive.json()},
                  {"cross_target_unchanged", cross_none.json()},
                  {"cg_iterations_mean", iterations.mean()},
                  {"cg_relative_residual_mean", residual.mean()},
                  {"transfer_ms_mean", ms.mean()},
                  {"subjects", subjects},
                  {"expressions", expressions.size()}};
  return out;
}

Result<nlohmann::json> image_transfer_bench(const FaceModel& model, int runs) {
  const auto expressions = photo_expressions(model);
  PhotoSpec spec;
  auto source = render_photo(model, spec);
  if (!source) return source.failure();
  spec.expression_weights = expressions[1].second;  // jaw open, brows up: the largest motion
  auto expr = render_photo(model, spec);
  if (!expr) return expr.failure();
  spec = {};
  spec.subject = 2;
  auto target = render_photo(model, spec);
  if (!target) return target.failure();
  Samples vtc_ms, warp_ms, vtc_warp_ms, vtc_solve_ms;
  int iterations = 0, unknowns = 0;
  for (int r = 0; r < runs; ++r) {
    auto t0 = Clock::now();
    auto out = transfer_image_expression(*source, *expr, *target);
    if (!out) return out.failure();
    vtc_ms.add(ms_since(t0));
    vtc_warp_ms.add(out->warp_ms);
    vtc_solve_ms.add(out->solve_ms);
    iterations = out->iterations;
    unknowns = out->region_pixels;
    t0 = Clock::now();
    auto warp = warp_expression(*source, *expr, *target);
    if (!warp) return warp.failure();
    warp_ms.add(ms_since(t0));
  }
  nlohmann::json out;
  out["image_transfer_ms"] = vtc_ms.min();
  out["image_warp_peer_ms"] = warp_ms.min();
  out["image_transfer_vs_warp_ratio"] = vtc_ms.min() / warp_ms.min();
  out["image"] = {{"width", target->image.width},
                  {"height", target->image.height},
                  {"unknowns", unknowns},
                  {"cg_iterations", iterations},
                  {"warp_ms", vtc_warp_ms.min()},
                  {"solve_ms", vtc_solve_ms.min()},
                  {"runs", runs},
                  {"peer",
                   "piecewise-affine landmark warp of the target alone "
                   "(algo/transfer/image_warp.hpp warp_expression)"}};
  return out;
}

namespace {

Result<void> write_photo(const FacePhoto& photo, const std::filesystem::path& stem) {
  auto png = encode_png(photo.image);
  if (!png) return png.failure();
  std::ofstream f(stem.string() + ".png", std::ios::binary);
  f.write(reinterpret_cast<const char*>(png->data()), static_cast<std::streamsize>(png->size()));
  std::ofstream l(stem.string() + ".txt");
  for (const auto& p : photo.points) l << p.x() << " " << p.y() << "\n";
  if (!f || !l) return fail("cannot write " + stem.string() + ".png/.txt");
  return success();
}

int run_render_transfer_image(const ParsedOptions& options) {
  const std::filesystem::path out = options.get("out");
  if (out.empty()) return report_failure({"--out DIR is required"});
  auto model = load_face_model();
  if (!model) return report_failure(model.error());
  auto weights = parse_expression_spec(options.get("expression"), *model);
  if (!weights) return report_failure(weights.error());
  auto target_subject = options.get_int("target-subject");
  if (!target_subject || *target_subject < 1) return report_failure({"--target-subject N >= 1"});
  std::error_code ec;
  std::filesystem::create_directories(out, ec);
  if (ec) return report_failure({"cannot create " + out.string() + ": " + ec.message()});
  PhotoSpec spec;
  const std::vector<std::pair<std::string, std::pair<std::uint64_t, bool>>> photos = {
      {"source_neutral", {1, false}},
      {"source_expr", {1, true}},
      {"target", {static_cast<std::uint64_t>(*target_subject), false}},
      {"target_truth", {static_cast<std::uint64_t>(*target_subject), true}}};
  for (const auto& [name, what] : photos) {
    spec.subject = what.first;
    spec.expression_weights = what.second ? *weights : std::vector<float>{};
    auto photo = render_photo(*model, spec);
    if (!photo) return report_failure(photo.error());
    if (auto ok = write_photo(*photo, out / name); !ok) return report_failure(ok.error());
  }
  std::cout << nlohmann::json{{"out", out.string()},
                              {"files",
                               {"source_neutral", "source_expr", "target", "target_truth"}}}
                   .dump(2)
            << std::endl;
  return kExitOk;
}

}  // namespace

Command render_transfer_image_command() {
  return {{"render transfer-image",
           "synthetic photographs for facebooth transfer-image (PNG + landmark files)",
           "Subject 1's neutral and expression photographs, the target subject's neutral and its "
           "true expression (the same recipe), 311 x 419 px, each NAME.png with NAME.txt (68 "
           "'x y' lines, the true landmarks).",
           {{"out", "DIR", "output folder", ""},
            {"expression", "SPEC", "the expression (synthetic camera expr= syntax)",
             "jawOpen:0.5+mouthSmile_L:0.6+mouthSmile_R:0.6+browInnerUp_L+browInnerUp_R"},
            {"target-subject", "N", "the target's subject seed", "2"}}},
          run_render_transfer_image};
}

}  // namespace fb::cli
