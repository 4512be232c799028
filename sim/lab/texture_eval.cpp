// `facebooth-lab eval texture`: the subject texture against the synthetic camera's painted skin.
// Per subject: a textured head turn is captured and fused, the neutral fitted from dlib's points
// on frame 0 (as on the device), the texture built from the take exactly as `facebooth
// texture` builds it, and compared texel by texel with the surface colour the renderer used.
#include <chrono>
#include <fstream>
#include <iostream>
#include <map>

#include <nlohmann/json.hpp>

#include "algo/core/clock.hpp"
#include "algo/core/polygon.hpp"
#include "algo/fitting/face_fit.hpp"
#include "algo/render/rasterizer.hpp"
#include "algo/texture/take_texture.hpp"
#include "host/cli/progress.hpp"
#include "host/cli/tracker_setup.hpp"
#include "sim/lab/lab_commands.hpp"
#include "sim/lab/raster_pixels.hpp"
#include "sim/scoring/take_runner.hpp"
#include "sim/subject/synthetic_capture.hpp"
#include "storage/asset_files.hpp"
#include "storage/export/png_file.hpp"

namespace fb::cli {

namespace {

Eigen::Vector3f sample(const ColorImage& atlas, float u, float v) {
  const float x = std::clamp(u * atlas.width - 0.5f, 0.0f, atlas.width - 1.0f);
  const float y = std::clamp((1.0f - v) * atlas.height - 0.5f, 0.0f, atlas.height - 1.0f);
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const int x1 = std::min(x0 + 1, atlas.width - 1), y1 = std::min(y0 + 1, atlas.height - 1);
  const float ax = x - x0, ay = y - y0;
  auto at = [&](int a, int b) {
    const Rgb8 c = atlas.at(a, b);
    return Eigen::Vector3f(c.r, c.g, c.b);
  };
  return (1 - ay) * ((1 - ax) * at(x0, y0) + ax * at(x1, y0)) +
         ay * ((1 - ax) * at(x0, y1) + ax * at(x1, y1));
}

// A UV of the atlas layout (FaceModel::atlas_uvs()).
Eigen::Vector2f uv_of(std::span<const float> uvs, std::uint32_t uv) {
  return {uvs[2 * uv], uvs[2 * uv + 1]};
}

// The visible face the score is over: triangles of the model's mean face inside the jaw line
// (landmarks 0-16) closed over the brows raised by 25 mm (the forehead), facing forward
// (normal z > 0.3): not the scalp, the ears, the neck or under the chin, which a frontal head
// turn sees at grazing angles or not at all.
std::vector<bool> visible_face_triangles(const FaceModel& m) {
  auto at = [&](std::uint32_t v) {
    return Eigen::Vector3f(m.neutral[3 * v], m.neutral[3 * v + 1], m.neutral[3 * v + 2]);
  };
  std::vector<Eigen::Vector2f> polygon;
  for (int l = 0; l <= 16; ++l) polygon.push_back(at(m.landmark_vertices[l]).head<2>());
  for (int l = 26; l >= 17; --l)
    polygon.push_back(at(m.landmark_vertices[l]).head<2>() + Eigen::Vector2f(0.0f, 25.0f));
  auto inside = [&](const Eigen::Vector2f& q) { return inside_polygon(polygon, q.x(), q.y()); };
  const std::vector<float> normals = vertex_normals(m.neutral, m.triangles);
  std::vector<bool> vertex_in(static_cast<std::size_t>(m.vertex_count), false);
  for (int v = 0; v < m.face_vertex_count; ++v)
    vertex_in[v] = normals[3 * v + 2] > 0.3f && inside(at(static_cast<std::uint32_t>(v)).head<2>());
  std::vector<bool> out(m.triangles.size() / 3, false);
  for (std::size_t t = 0; t < out.size(); ++t)
    out[t] = vertex_in[m.triangles[3 * t]] && vertex_in[m.triangles[3 * t + 1]] &&
             vertex_in[m.triangles[3 * t + 2]];
  return out;
}

struct AtlasScore {
  double psnr_db = 0.0;
  Eigen::Vector3d gain = Eigen::Vector3d::Ones();
  int texels = 0;
  double seam_error = 0.0;  // mean |difference| across UV seams, 8-bit levels
  int seam_samples = 0;
  int seam_edges = 0;
  int seam_samples_observed = 0;  // both sides seen by a frame (the rest are filled)
};

// PSNR over the observed face texels after one least-squares gain per channel (the camera's
// exposure and white balance make absolute albedo unobservable).
AtlasScore score_atlas(const FaceModel& model, std::span<const float> uvs,
                       const std::vector<bool>& face, const TexelMap& map,
                       const TextureAtlas& atlas, const SyntheticCamera& truth) {
  AtlasScore s;
  std::vector<Eigen::Vector3d> want, got;
  Eigen::Vector3d xy = Eigen::Vector3d::Zero(), xx = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < map.triangle.size(); ++i) {
    if (map.triangle[i] < 0 || !(atlas.weight.pixels[i] > 0.0f) || atlas.clipped.pixels[i])
      continue;
    if (!face[static_cast<std::size_t>(map.triangle[i])]) continue;
    want.push_back(
        255.0 *
        truth.surface_albedo(map.triangle[i], map.bary[i][1], map.bary[i][2]).cast<double>());
    const Rgb8 c = atlas.image.pixels[i];
    got.emplace_back(c.r, c.g, c.b);
    xy += got.back().cwiseProduct(want.back());
    xx += got.back().cwiseProduct(got.back());
  }
  s.texels = static_cast<int>(want.size());
  if (want.empty()) return s;
  s.gain = xy.cwiseQuotient(xx.cwiseMax(1e-9));
  double se = 0.0;
  for (std::size_t k = 0; k < want.size(); ++k)
    se += (got[k].cwiseProduct(s.gain) - want[k]).squaredNorm() / 3.0;
  s.psnr_db = 10.0 * std::log10(255.0 * 255.0 / std::max(se / want.size(), 1e-9));
  // Seams: an edge shared by two triangles whose corners have different UVs; the atlas
  // must show the same colour on both sides.
  std::map<std::pair<std::uint32_t, std::uint32_t>, std::pair<std::size_t, int>> first;
  double diff = 0.0;
  for (std::size_t t = 0; t < model.triangles.size() / 3; ++t) {
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t a = model.triangles[3 * t + k], b = model.triangles[3 * t + (k + 1) % 3];
      const auto key = std::minmax(a, b);
      auto [it, inserted] = first.try_emplace({key.first, key.second}, t, k);
      if (inserted) continue;
      const auto [t2, k2] = it->second;
      // Corner UVs of the edge's two vertices in either triangle, in (a, b) order.
      auto corner_uv = [&](std::size_t tri, std::uint32_t v) {
        for (int c = 0; c < 3; ++c)
          if (model.triangles[3 * tri + c] == v) return model.triangle_uvs[3 * tri + c];
        return model.triangle_uvs[3 * tri];
      };
      const auto a1 = corner_uv(t, a), b1 = corner_uv(t, b);
      const auto a2 = corner_uv(t2, a), b2 = corner_uv(t2, b);
      if (a1 == a2 && b1 == b2) continue;  // not a seam
      ++s.seam_edges;
      for (float f = 0.1f; f < 0.95f; f += 0.2f) {
        const Eigen::Vector2f p = (1 - f) * uv_of(uvs, a1) + f * uv_of(uvs, b1);
        const Eigen::Vector2f q = (1 - f) * uv_of(uvs, a2) + f * uv_of(uvs, b2);
        auto seen = [&](const Eigen::Vector2f& uv) {
          const int x = std::clamp(static_cast<int>(uv.x() * map.width), 0, map.width - 1);
          const int y =
              std::clamp(static_cast<int>((1.0f - uv.y()) * map.height), 0, map.height - 1);
          return atlas.weight.at(x, y) > 0.0f;
        };
        const bool observed = seen(p) && seen(q);
        diff += (sample(atlas.image, p.x(), p.y()) - sample(atlas.image, q.x(), q.y()))
                    .cwiseAbs()
                    .mean();
        ++s.seam_samples;
        s.seam_samples_observed += observed;
      }
    }
  }
  s.seam_error = s.seam_samples ? diff / s.seam_samples : 0.0;
  return s;
}

// The atlas as it shows on the fitted surface: a visible-face texel's fitted point (frame 0),
// seen by the depth camera, lands on the true surface at some point; the painted colour there is
// what the avatar should show at that texel. Unlike the UV-space score this leaves out the fit's
// correspondence error (a lip vertex fitted 2 mm low shows the skin below the lip, correctly for
// the still avatar, wrongly once the rig moves the lip).
double surface_psnr_db(const FaceModel& model, const std::vector<bool>& face, const TexelMap& map,
                       const TextureAtlas& atlas, std::span<const float> fitted,
                       const RigidPose& fitted_pose, std::span<const float> truth_mesh,
                       const RigidPose& truth_pose, const PinholeIntrinsics& k,
                       const SyntheticCamera& truth) {
  std::vector<Eigen::Vector3f> posed(truth_mesh.size() / 3);
  for (std::size_t v = 0; v < posed.size(); ++v)
    posed[v] =
        truth_pose
            .apply(Eigen::Vector3d(truth_mesh[3 * v], truth_mesh[3 * v + 1], truth_mesh[3 * v + 2]))
            .cast<float>();
  RasterBuffers raster;
  raster.reset(k.width, k.height);
  if (!rasterize(k, posed, model.triangles, {}, raster)) return 0.0;
  Eigen::Vector3d xy = Eigen::Vector3d::Zero(), xx = Eigen::Vector3d::Zero();
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> pairs;
  for (std::size_t i = 0; i < map.triangle.size(); ++i) {
    if (map.triangle[i] < 0 || !(atlas.weight.pixels[i] > 0.0f) || atlas.clipped.pixels[i])
      continue;
    if (!face[static_cast<std::size_t>(map.triangle[i])]) continue;
    const Eigen::Vector3d q =
        fitted_pose.apply(texel_point(map, i, model.triangles, fitted).cast<double>());
    const Eigen::Vector2d px = k.project(q);
    const int x = static_cast<int>(std::lround(px.x())), y = static_cast<int>(std::lround(px.y()));
    if (x < 0 || y < 0 || x >= k.width || y >= k.height) continue;
    const std::size_t j = raster.index(x, y);
    if (raster.triangle[j] == kNoTriangle || std::abs(raster.depth[j] - q.z()) > 5.0) continue;
    const Eigen::Vector3d want =
        255.0 *
        truth.surface_albedo(raster.triangle[j], raster.bary1[j], raster.bary2[j]).cast<double>();
    const Rgb8 c = atlas.image.pixels[i];
    const Eigen::Vector3d got(c.r, c.g, c.b);
    xy += got.cwiseProduct(want);
    xx += got.cwiseProduct(got);
    pairs.emplace_back(got, want);
  }
  if (pairs.empty()) return 0.0;
  const Eigen::Vector3d gain = xy.cwiseQuotient(xx.cwiseMax(1e-9));
  double se = 0.0;
  for (const auto& [got, want] : pairs) se += (got.cwiseProduct(gain) - want).squaredNorm() / 3.0;
  return 10.0 * std::log10(255.0 * 255.0 / std::max(se / pairs.size(), 1e-9));
}

// The textured avatar drawn by the project's rasterizer from a camera pose, lit by a soft key
// light (the atlas is de-lit), on grey.
ColorImage render_avatar(const FaceModel& model, std::span<const float> uvs,
                         std::span<const float> vertices, const RigidPose& camera_from_model,
                         const ColorImage& atlas, const PinholeIntrinsics& k) {
  std::vector<Eigen::Vector3f> posed(vertices.size() / 3);
  const std::vector<float> normals = vertex_normals(vertices, model.triangles);
  const Eigen::Matrix3f r = camera_from_model.rotation.toRotationMatrix().cast<float>();
  for (std::size_t v = 0; v < posed.size(); ++v)
    posed[v] = r * Eigen::Vector3f(vertices[3 * v], vertices[3 * v + 1], vertices[3 * v + 2]) +
               camera_from_model.translation.cast<float>();
  RasterBuffers raster;
  raster.reset(k.width, k.height);
  ColorImage out;
  out.resize(k.width, k.height);
  std::fill(out.pixels.begin(), out.pixels.end(), Rgb8{96, 96, 96});
  if (!rasterize(k, posed, model.triangles, {}, raster)) return out;
  const Eigen::Vector3f light = Eigen::Vector3f(-0.3f, -0.4f, -1.0f).normalized();
  for_each_covered_pixel(raster, [&](const RasterPixel& p) {
    Eigen::Vector2f uv = Eigen::Vector2f::Zero();
    for (int c = 0; c < 3; ++c)
      uv += p.bary[c] * uv_of(uvs, model.triangle_uvs[3 * p.triangle + c]);
    const Eigen::Vector3f n = interpolate(normals, model.triangles, p);
    const float shade = 0.45f + 0.6f * std::max(0.0f, (r * n.normalized()).dot(light));
    const Eigen::Vector3f c = (sample(atlas, uv.x(), uv.y()) * shade).cwiseMin(255.0f);
    out.at(p.x, p.y) = Rgb8{static_cast<std::uint8_t>(c.x()), static_cast<std::uint8_t>(c.y()),
                            static_cast<std::uint8_t>(c.z())};
  });
  return out;
}

// A square crop of `image` centred on `centre`, `side` px, scaled to `out_side`.
ColorImage crop(const ColorImage& image, const Eigen::Vector2d& centre, int side, int out_side) {
  ColorImage out;
  out.resize(out_side, out_side);
  for (int y = 0; y < out_side; ++y)
    for (int x = 0; x < out_side; ++x) {
      const int sx = static_cast<int>(centre.x() - side / 2.0 + (x + 0.5) * side / out_side);
      const int sy = static_cast<int>(centre.y() - side / 2.0 + (y + 0.5) * side / out_side);
      out.at(x, y) = image.contains(sx, sy) ? image.at(sx, sy) : Rgb8{0, 0, 0};
    }
  return out;
}

Result<void> write_picture(const std::string& path, const std::vector<ColorImage>& panels) {
  ColorImage sheet;
  const int side = panels.front().height;
  sheet.resize(side * static_cast<int>(panels.size()), side);
  for (std::size_t p = 0; p < panels.size(); ++p)
    for (int y = 0; y < side; ++y)
      for (int x = 0; x < side; ++x)
        sheet.at(static_cast<int>(p) * side + x, y) = panels[p].at(x, y);
  return write_png_file(path, sheet);
}

constexpr const char* kTextureScoring =
    "PSNR over the visible face (inside the jaw line, up to 25 mm above the brows, facing "
    "forward; observed, not over-exposed in every view) against the renderer's surface colour, "
    "after one least-squares gain per channel (exposure is unobservable), in the atlas's UV "
    "space (so the fit's correspondence error counts); _on_fitted_surface: each texel against "
    "the painted colour where its fitted point lands on the true surface (the still avatar's "
    "appearance); seam error: mean absolute 8-bit difference of the atlas across UV seams of "
    "the face, both sides observed";

// One subject's line of the JSON.
nlohmann::json run_json(std::uint64_t seed, const AtlasScore& score, double on_surface,
                        double observed, const TakeTexture& tex, double fit_rms_mm,
                        double seconds) {
  return nlohmann::json({{"seed", seed},
                         {"texture_psnr_db", score.psnr_db},
                         {"texture_seam_error", score.seam_error},
                         {"texture_psnr_db_on_fitted_surface", on_surface},
                         {"seam_samples", score.seam_samples},
                         {"seam_edges", score.seam_edges},
                         {"seam_samples_observed", score.seam_samples_observed},
                         {"face_texels_scored", score.texels},
                         {"gain", {score.gain.x(), score.gain.y(), score.gain.z()}},
                         {"observed_fraction", observed},
                         {"frames_aligned", tex.frames_aligned},
                         {"views", tex.views.size()},
                         {"fit_rms_to_depth_mm", fit_rms_mm},
                         {"texture_s", seconds}});
}

// The fit's inner landmarks (17-67) on the mesh and their lifted camera points: the pairs that
// place the mesh on the take's first frame.
struct LandmarkPairs {
  std::vector<Eigen::Vector3d> model, camera;
};
LandmarkPairs landmark_pairs(const FaceModel& model, const std::vector<float>& vertices,
                             const FitTarget& target) {
  LandmarkPairs pairs;
  for (int l = 17; l < 68; ++l) {
    const auto& lm = target.landmarks[static_cast<std::size_t>(l)];
    if (!lm.valid || !lm.point) continue;
    const auto v = target.landmark_vertices
                       ? (*target.landmark_vertices)[static_cast<std::size_t>(l)]
                       : model.landmark_vertices[static_cast<std::size_t>(l)];
    pairs.model.emplace_back(vertices[3 * v], vertices[3 * v + 1], vertices[3 * v + 2]);
    pairs.camera.push_back(*lm.point);
  }
  return pairs;
}

// The README's picture: the captured colour frame beside the textured avatar, frontal and turned.
Result<void> write_avatar_picture(const std::string& path, const FaceModel& model,
                                  const std::vector<float>& atlas_uvs,
                                  const std::vector<float>& vertices, const TakeTexture& tex,
                                  const Capture& cap, const std::vector<Eigen::Vector2d>& points) {
  const auto& k = cap.intrinsics;
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  for (const auto& p : points) centre += p / 68.0;
  RigidPose turned = tex.poses.front();
  const Eigen::Vector3d pivot = turned.apply(Eigen::Vector3d::Zero());
  turned.rotation = Eigen::AngleAxisd(0.6, Eigen::Vector3d::UnitY()) * turned.rotation;
  turned.translation = pivot;
  const ColorImage front =
      render_avatar(model, atlas_uvs, vertices, tex.poses.front(), tex.atlas.image, k);
  const ColorImage side = render_avatar(model, atlas_uvs, vertices, turned, tex.atlas.image, k);
  const auto nose = model.landmark_vertices[30];
  const Eigen::Vector3d tip(vertices[3 * nose], vertices[3 * nose + 1], vertices[3 * nose + 2]);
  const Eigen::Vector2d rendered_centre = k.project(tex.poses.front().apply(tip));
  const Eigen::Vector2d side_centre = k.project(turned.apply(tip));
  const int crop_px = 220, out_px = 320;
  return write_picture(path, {crop(cap.color, centre, crop_px, out_px),
                              crop(front, rendered_centre, crop_px, out_px),
                              crop(side, side_centre, crop_px, out_px)});
}

// What one subject's run is given: the lab's choices and what is loaded once.
struct TextureEvalSetup {
  const FaceModel* model = nullptr;
  std::vector<float> atlas_uvs;
  const TexelMap* map = nullptr;
  std::vector<bool> face;
  LandmarkDetector* detector = nullptr;  // null: true landmarks
  const LandmarkEmbedding* embedding = nullptr;
  TakeTextureOptions texture;
  std::string world;
  int frames = 90;
  bool truth_mesh = false;  // texture the true mesh (an upper bound: no fit error)
  std::string png;
};

struct SubjectTexture {
  nlohmann::json json;
  AtlasScore score;
  double on_surface = 0.0, observed = 0.0, seconds = 0.0;
};

// One synthetic subject: capture, fit from frame 0's landmarks, texture as the product does
// (texture_capture's inputs), score.
Result<SubjectTexture> texture_subject(const TextureEvalSetup& setup, std::uint64_t seed,
                                       bool picture) {
  const FaceModel& model = *setup.model;
  const std::vector<float> identity = identity_draw(seed, model.identity_count);
  const std::vector<float> neutral(static_cast<std::size_t>(model.expression_count), 0.0f);
  auto cap = capture(model, identity, neutral, seed, setup.frames, false, {}, setup.world, seed,
                     UnitCalibration::kCalibrated, setup.detector, true);
  if (!cap) return cap.failure();
  std::vector<Eigen::Vector2d> points = cap->truth_color_px;
  if (setup.detector) {
    setup.detector->reset_tracking();
    auto found = setup.detector->detect(cap->color);
    if (!found) return fail("dlib: " + found.error().message);
    points.assign(found->points.begin(), found->points.end());
  }
  auto target = make_fit_target(*cap, points, false);
  if (!target) return target.failure();
  if (setup.detector && setup.embedding)
    target->landmark_vertices = setup.embedding->for_expression("neutral");  // as the device
  auto fit = fit_neutral(model, *target);
  if (!fit) return fit.failure();
  const std::vector<float>& mesh = setup.truth_mesh ? cap->truth_mesh : fit->vertices;
  const LandmarkPairs pairs = landmark_pairs(model, mesh, *target);
  const TakeTextureInput in{mesh,        model.triangles, model.face_vertex_count,
                            cap->frames, pairs.model,     pairs.camera,
                            std::nullopt};
  const KinectRegistration registration(cap->calibration);
  const auto t0 = Clock::now();
  auto tex = texture_from_take(*setup.map, in, registration, setup.texture);
  SubjectTexture out;
  out.seconds = seconds_since(t0);
  if (!tex) return tex.failure();
  out.score = score_atlas(model, setup.atlas_uvs, setup.face, *setup.map, tex->atlas, *cap->camera);
  out.on_surface =
      surface_psnr_db(model, setup.face, *setup.map, tex->atlas, mesh, tex->poses.front(),
                      cap->truth_mesh, cap->truth_pose, cap->intrinsics, *cap->camera);
  out.observed = static_cast<double>(tex->atlas.report.observed_texels) /
                 std::max(1, tex->atlas.report.covered_texels);
  out.json = run_json(seed, out.score, out.on_surface, out.observed, *tex, fit->rms_to_depth_mm,
                      out.seconds);
  if (picture && !setup.png.empty())
    if (auto ok = write_avatar_picture(setup.png, model, setup.atlas_uvs, mesh, *tex, *cap, points);
        !ok)
      return ok.failure();
  return out;
}

// The lab's choices from the command line.
Result<void> texture_eval_options(const ParsedOptions& options, TextureEvalSetup& setup) {
  auto frames = options.get_int("frames");
  auto views = options.get_int("views");
  if (!frames) return frames.failure();
  if (!views) return views.failure();
  if (*frames < 2) return fail("--frames >= 2");
  setup.frames = static_cast<int>(*frames);
  setup.texture.max_views = static_cast<int>(*views);
  setup.texture.texture.delight = !options.flag("no-delight");
  setup.world = options.get("world");
  setup.png = options.get("png");
  if (options.get("mesh") != "fitted" && options.get("mesh") != "truth")
    return fail("--mesh is fitted or truth");
  setup.truth_mesh = options.get("mesh") == "truth";
  return success();
}

int run_eval_texture(const ParsedOptions& options) {
  auto subjects = options.get_int("subjects");
  auto first = options.get_int("first-seed");
  auto size = options.get_int("size");
  for (const auto* r : {&subjects, &first, &size})
    if (!*r) return report_failure(r->error());
  if (*subjects < 1) return report_failure({"--subjects >= 1"});
  TextureEvalSetup setup;
  if (auto ok = texture_eval_options(options, setup); !ok) return report_failure(ok.error());
  auto model = load_face_model();
  if (!model) return report_failure(model.error());
  setup.model = &*model;
  setup.atlas_uvs = model->atlas_uvs();
  auto map = make_texel_map(setup.atlas_uvs, model->triangle_uvs,
                            static_cast<int>(*size) * model->uv_tiles(), static_cast<int>(*size));
  if (!map) return report_failure(map.error());
  setup.map = &*map;
  const bool dlib = options.get("landmarks") == "dlib";
  if (!dlib && options.get("landmarks") != "truth")
    return report_failure({"--landmarks is dlib or truth"});
  std::optional<LandmarkDetector> detector;
  if (dlib) {
    auto d = load_landmark_detector(options.get("shape-predictor"));
    if (!d) return report_failure(d.error());
    detector.emplace(std::move(*d));
    setup.detector = &*detector;
  }
  // dlib's points mark the vertices of the shipped embedding, as on the device.
  auto embedding = landmark_embedding_beside(*model, default_face_model_path());
  if (!embedding) return report_failure(embedding.error());
  if (*embedding) setup.embedding = &**embedding;
  setup.face = visible_face_triangles(*model);
  nlohmann::json runs = nlohmann::json::array();
  double psnr_sum = 0, surface_sum = 0, psnr_min = 1e9, seam_sum = 0, seconds_sum = 0,
         seconds_max = 0, seen = 0;
  Progress progress("eval texture", *subjects);
  for (long long s = 0; s < *subjects; ++s) {
    const auto seed = static_cast<std::uint64_t>(*first + s);
    auto r = texture_subject(setup, seed, s == 0);
    if (!r) return report_failure({"subject " + std::to_string(seed) + ": " + r.error().message});
    runs.push_back(r->json);
    psnr_sum += r->score.psnr_db;
    surface_sum += r->on_surface;
    psnr_min = std::min(psnr_min, r->score.psnr_db);
    seam_sum += r->score.seam_error;
    seconds_sum += r->seconds;
    seconds_max = std::max(seconds_max, r->seconds);
    seen += r->observed;
    progress.update(s + 1);
  }
  const double n = static_cast<double>(*subjects);
  nlohmann::json out = {
      {"subjects", *subjects},
      {"world", setup.world},
      {"landmarks", dlib ? "dlib on frame 0 (as the device)" : "truth"},
      {"mesh", setup.truth_mesh ? "truth (upper bound)" : "fitted"},
      {"atlas_size", *size},
      {"texture_psnr_db", psnr_sum / n},
      {"texture_psnr_db_min", psnr_min},
      {"texture_psnr_db_on_fitted_surface", surface_sum / n},
      {"texture_seam_error", seam_sum / n},
      {"observed_fraction", seen / n},
      {"texture_s", seconds_sum / n},
      {"texture_s_max", seconds_max},
      {"budget", {{"texture_psnr_db", ">= 30"}, {"texture_s", "<= 3 (one core)"}}},
      {"scoring", kTextureScoring},
      {"runs", runs}};
  std::cout << out.dump(2) << "\n";
  return kExitOk;
}

}  // namespace

std::vector<Command> texture_eval_commands() {
  return {
      {{"eval texture",
        "the subject texture against the synthetic camera's painted skin (JSON)",
        "Per subject a textured synthetic head turn (world preset --world), fused; the "
        "neutral is fitted from --landmarks on frame 0 and textured as `facebooth texture` "
        "does. texture_s: the texture step alone (alignment to every frame + atlas), one "
        "thread. --png writes the first subject's colour frame next to its textured avatar "
        "drawn by the project's rasterizer, frontal and turned.",
        {{"subjects", "N", "synthetic subjects", "3"},
         {"first-seed", "N", "seed of the first subject", "1"},
         {"frames", "N", "frames per head turn", "90"},
         {"size", "PX", "atlas height (its width: one square per UV tile)", "1024"},
         {"views", "N", "frames blended (spread over the take)", "15"},
         {"mesh", "fitted|truth", "texture the fitted or (an upper bound) the true mesh", "fitted"},
         {"no-delight", "", "keep the frames' shading in the atlas (for comparison)", ""},
         {"world", "PRESET", "synthetic world preset (world_presets.hpp)", "texture"},
         {"landmarks", "dlib|truth", "the fit's landmarks on frame 0", "dlib"},
         {"shape-predictor", "FILE", "dlib's 68-point model", ""},
         {"png", "FILE", "picture: colour frame | avatar | avatar turned", ""},
         {"json", "", "JSON report on stdout (the only output format)", ""}}},
       run_eval_texture}};
}

}  // namespace fb::cli
