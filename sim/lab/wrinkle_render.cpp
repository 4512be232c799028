// `facebooth-lab render wrinkles`: the README's before/after picture (issue 40). A synthetic
// subject's raised-brow expression (eval wrinkles' grooves case), rendered with algo/render's
// rasterizer at twice the frame's resolution under a raking light from above: the booth's colour
// frame it started from, the fitted mesh alone (before), and the mesh with the synthesised
// detail as the exports carry it (after: the tangent-space normal map in the face model's UV
// layout, looked up per pixel through each triangle's UV frame), and the same maps made from the
// case's true relief (what a perfect synthesis would give).
#include <algorithm>
#include <cmath>
#include <iostream>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "algo/core/mesh_normals.hpp"
#include "algo/render/rasterizer.hpp"
#include "algo/texture/texel_map.hpp"
#include "algo/wrinkles/capture_detail.hpp"
#include "algo/wrinkles/wrinkle_geometry.hpp"
#include "host/cli/wrinkle_exemplar_files.hpp"
#include "sim/lab/lab_commands.hpp"
#include "sim/lab/wrinkle_case.hpp"
#include "storage/asset_files.hpp"

namespace fb::cli {

namespace {

constexpr int kZoom = 3;

struct Scene {
  const FaceModel* model = nullptr;
  const WrinkleCase* c = nullptr;
  std::vector<float> uvs;  // atlas layout
  std::vector<float> normals;
  RasterBuffers raster;
  PinholeIntrinsics k;
};

Eigen::Vector3f vec(std::span<const float> v, std::uint32_t i) {
  return {v[3 * i], v[3 * i + 1], v[3 * i + 2]};
}

// The shading normal (model frame) at a pixel: the smooth vertex normal, tilted by the normal
// map when one is given.
Eigen::Vector3f pixel_normal(const Scene& s, std::size_t i, const DetailMaps* maps) {
  const auto t = static_cast<std::size_t>(s.raster.triangle[i]);
  const float b1 = s.raster.bary1[i], b2 = s.raster.bary2[i], b0 = 1.0f - b1 - b2;
  const float b[3] = {b0, b1, b2};
  const auto& tris = s.model->triangles;
  Eigen::Vector3f n = Eigen::Vector3f::Zero();
  for (int k = 0; k < 3; ++k) n += b[k] * vec(s.normals, tris[3 * t + k]);
  n.normalize();
  if (maps == nullptr) return n;
  Eigen::Vector2f uv = Eigen::Vector2f::Zero(), q[3];
  Eigen::Vector3f p[3];
  for (int k = 0; k < 3; ++k) {
    const std::uint32_t u = s.model->triangle_uvs[3 * t + k];
    q[k] = {s.uvs[2 * u], s.uvs[2 * u + 1]};
    p[k] = vec(s.c->vertices, tris[3 * t + k]);
    uv += b[k] * q[k];
  }
  Eigen::Matrix<float, 3, 2> e;
  e << p[1] - p[0], p[2] - p[0];
  Eigen::Matrix2f f;
  f << q[1] - q[0], q[2] - q[0];
  if (std::abs(f.determinant()) < 1e-12f) return n;
  const Eigen::Matrix<float, 3, 2> j = e * f.inverse();
  const ColorImage& nm = maps->normal_map;
  const int x = std::clamp(static_cast<int>(uv.x() * nm.width), 0, nm.width - 1);
  const int y = std::clamp(static_cast<int>((1.0f - uv.y()) * nm.height), 0, nm.height - 1);
  const Rgb8 c = nm.at(x, y);
  const Eigen::Vector3f local(c.r / 127.5f - 1.0f, c.g / 127.5f - 1.0f, c.b / 127.5f - 1.0f);
  if (c.r == 128 && c.g == 128 && c.b == 255) return n;
  Eigen::Vector3f tu = j.col(0) - n * n.dot(j.col(0));
  tu.normalize();
  const Eigen::Vector3f tv = n.cross(tu);
  return (local.x() * tu + local.y() * tv + local.z() * n).normalized();
}

cv::Mat shade(const Scene& s, const DetailMaps* maps, const cv::Rect& crop) {
  cv::Mat out(crop.height, crop.width, CV_8UC3, cv::Scalar(40, 40, 40));
  const Eigen::Matrix3f to_model =
      s.c->camera_from_model.rotation.conjugate().toRotationMatrix().cast<float>();
  // Raking light from above (camera -y) and a little from the left, so furrows show.
  const Eigen::Vector3f light = (to_model * Eigen::Vector3f(-0.25f, -0.85f, -0.45f)).normalized();
  for (int y = 0; y < crop.height; ++y)
    for (int x = 0; x < crop.width; ++x) {
      const std::size_t i = s.raster.index(crop.x + x, crop.y + y);
      if (s.raster.triangle[i] == kNoTriangle) continue;
      const Eigen::Vector3f n = pixel_normal(s, i, maps);
      const float v = 0.15f + 0.8f * std::max(0.0f, n.dot(light));
      const auto g = static_cast<std::uint8_t>(std::clamp(v * 230.0f, 0.0f, 255.0f));
      out.at<cv::Vec3b>(y, x) = {g, g, g};
    }
  return out;
}

void label(cv::Mat& m, const std::string& text) {
  cv::putText(m, text, {8, 20}, cv::FONT_HERSHEY_SIMPLEX, 0.55, cv::Scalar(0, 220, 255), 1,
              cv::LINE_AA);
}

int run_render_wrinkles(const ParsedOptions& options) {
  const std::string png = options.get("png");
  if (png.empty()) return report_failure({"give --png FILE"});
  auto seed = options.get_int("seed");
  if (!seed) return report_failure(seed.error());
  auto model = load_face_model();
  if (!model) return report_failure(model.error());
  auto set = load_exemplar_set(default_exemplar_directory());
  if (!set) return report_failure(set.error());
  WrinkleCaseOptions co;
  co.seed = static_cast<std::uint64_t>(*seed);
  auto c = make_wrinkle_case(*model, co);
  if (!c) return report_failure(c.error());
  auto neutral = make_neutral_case(*model, co);
  if (!neutral) return report_failure(neutral.error());
  const CaseFace face(*c, *model, &*neutral);  // the product's input: the ratio to the neutral
  WrinkleDetailOptions wo;
  wo.exemplar_mm_per_px = set->mm_per_px;
  auto d = wrinkle_detail(c->luminance, c->landmarks, c->face_depth_mm, c->intrinsics.fx,
                          set->exemplars, wo, &face.face);
  if (!d) return report_failure(d.error());
  Scene s;
  s.model = &*model;
  s.c = &*c;
  s.uvs = model->atlas_uvs();
  auto map = make_texel_map(s.uvs, model->triangle_uvs, 1024 * model->uv_tiles(), 1024);
  if (!map) return report_failure(map.error());
  HeightView view{&d->synthesis.height_mm, &d->synthesis.domain, c->camera_from_model,
                  c->intrinsics};
  auto maps = detail_maps(*map, s.uvs, model->triangle_uvs, c->vertices, model->triangles, view);
  if (!maps) return report_failure(maps.error());
  // The same maps from the true relief (what a perfect synthesis would give).
  Image<std::uint8_t> everywhere;
  everywhere.resize(c->true_height_mm.width, c->true_height_mm.height);
  std::fill(everywhere.pixels.begin(), everywhere.pixels.end(), std::uint8_t{1});
  HeightView true_view{&c->true_height_mm, &everywhere, c->camera_from_model, c->intrinsics};
  auto true_maps =
      detail_maps(*map, s.uvs, model->triangle_uvs, c->vertices, model->triangles, true_view);
  if (!true_maps) return report_failure(true_maps.error());
  s.normals = vertex_normals(c->vertices, model->triangles);
  s.k = c->intrinsics;
  s.k.width *= kZoom, s.k.height *= kZoom, s.k.fx *= kZoom, s.k.fy *= kZoom;
  s.k.cx = kZoom * s.k.cx + 0.5, s.k.cy = kZoom * s.k.cy + 0.5;
  std::vector<Eigen::Vector3f> posed(c->vertices.size() / 3);
  for (std::size_t v = 0; v < posed.size(); ++v)
    posed[v] = c->camera_from_model.apply(vec(c->vertices, v).cast<double>()).cast<float>();
  s.raster.reset(s.k.width, s.k.height);
  if (auto ok = rasterize(s.k, posed, model->triangles, {}, s.raster); !ok)
    return report_failure(ok.error());
  // The upper face: jaw-line width, from above the forehead lines to the nose's middle.
  const auto& lm = c->landmarks;
  const double top = std::min(lm[19].y(), lm[24].y()) - 1.5 * (lm[30].y() - lm[27].y());
  cv::Rect crop(static_cast<int>(kZoom * (lm[0].x() - 4)), static_cast<int>(kZoom * top),
                static_cast<int>(kZoom * (lm[16].x() - lm[0].x() + 8)),
                static_cast<int>(kZoom * (lm[29].y() - top)));
  crop &= cv::Rect(0, 0, s.k.width, s.k.height);
  cv::Mat frame(c->color.height, c->color.width, CV_8UC3);
  for (int y = 0; y < c->color.height; ++y)
    for (int x = 0; x < c->color.width; ++x) {
      const Rgb8 p = c->color.at(x, y);
      frame.at<cv::Vec3b>(y, x) = {p.b, p.g, p.r};
    }
  cv::Mat big;
  cv::resize(frame, big, {s.k.width, s.k.height}, 0, 0, cv::INTER_NEAREST);
  cv::Mat panels[4] = {big(crop).clone(), shade(s, nullptr, crop), shade(s, &*maps, crop),
                       shade(s, &*true_maps, crop)};
  label(panels[0], "colour frame (input)");
  label(panels[1], "before: the mesh");
  label(panels[2], "after: synthesised detail");
  label(panels[3], "true relief, same maps");
  cv::Mat all;
  cv::hconcat(panels, 4, all);
  if (!cv::imwrite(png, all)) return report_failure({"cannot write " + png});
  nlohmann::json out = {{"png", png},
                        {"seed", *seed},
                        {"texels_with_detail", maps->texels_with_detail},
                        {"regions", d->regions.regions.size()},
                        {"size", std::to_string(all.cols) + "x" + std::to_string(all.rows)}};
  std::cout << out.dump(2) << "\n";
  return kExitOk;
}

}  // namespace

std::vector<Command> wrinkle_render_commands() {
  return {{{"render wrinkles",
            "before/after picture of a synthetic raised-brow expression with its wrinkle detail",
            "The grooves case of eval wrinkles (subject SEED): its colour frame, the mesh shaded "
            "under a raking light, the same with the synthesised normal map in the UV layout, "
            "and with the maps of the true relief. Upper face, 3x the frame's resolution.",
            {{"png", "FILE", "where to write the picture", ""}, {"seed", "N", "subject", "1"}}},
           run_render_wrinkles}};
}

}  // namespace fb::cli
