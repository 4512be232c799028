#include "sim/lab/wrinkle_case.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>

#include "algo/core/mix64.hpp"
#include "algo/render/rasterizer.hpp"
#include "sim/camera/synthetic_camera.hpp"

namespace fb::cli {

namespace {

constexpr int kSuper = 3;  // samples per pixel side

float smoothstep(float e0, float e1, float x) {
  const float t = std::clamp((x - e0) / (e1 - e0), 0.0f, 1.0f);
  return t * t * (3.0f - 2.0f * t);
}

// A window of relief on the model's frontal plane: local u along `axis`, v a quarter turn
// counter-clockwise (model +Y up), faded to 0 over `taper_mm` at its edges.
struct ReliefWindow {
  Eigen::Vector2f origin, axis;
  float u0, u1, v0, v1, taper_mm = 3.0f;
  std::function<float(float, float)> height;

  Eigen::Vector2f local(const Eigen::Vector2f& p) const {
    const Eigen::Vector2f d = p - origin;
    return {d.dot(axis), d.dot(Eigen::Vector2f(-axis.y(), axis.x()))};
  }
  float weight(const Eigen::Vector2f& uv) const {
    const float e = std::min({uv.x() - u0, u1 - uv.x(), uv.y() - v0, v1 - uv.y()});
    return e <= 0.0f ? 0.0f : smoothstep(0.0f, taper_mm, e);
  }
};

float groove(float distance_mm, float depth_mm, float sigma_mm) {
  return -depth_mm * std::exp(-0.5f * distance_mm * distance_mm / (sigma_mm * sigma_mm));
}

float bilinear(const FloatImage& im, float x, float y) {
  x = std::clamp(x, 0.0f, im.width - 1.001f);
  y = std::clamp(y, 0.0f, im.height - 1.001f);
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const float ax = x - x0, ay = y - y0;
  return (1 - ay) * ((1 - ax) * im.at(x0, y0) + ax * im.at(x0 + 1, y0)) +
         ay * ((1 - ax) * im.at(x0, y0 + 1) + ax * im.at(x0 + 1, y0 + 1));
}

// A crop (image y down = skin up) centred on (uc, vc) of a window, at `mm_per_px`.
std::function<float(float, float)> crop_relief(const FloatImage& crop, double mm_per_px, float uc,
                                               float vc) {
  const auto s = static_cast<float>(mm_per_px);
  return [&crop, s, uc, vc](float u, float v) {
    return bilinear(crop, 0.5f * crop.width + (u - uc) / s, 0.5f * crop.height - (v - vc) / s);
  };
}

const WrinkleExemplar* find_crop(const WrinkleCaseOptions& o, const std::string& name) {
  for (const auto& e : o.scan_crops)
    if (e.name == name) return &e;
  return nullptr;
}

// The forehead band above the raised brows and both eye corners' crow's feet.
Result<std::vector<ReliefWindow>> relief_windows(std::span<const Eigen::Vector3f> lm,
                                                 const WrinkleCaseOptions& o) {
  float brow_top = -1e9f;
  for (int i = 17; i <= 26; ++i) brow_top = std::max(brow_top, lm[i].y());
  const float half_width = 0.5f * (lm[24].x() - lm[19].x()) + 6.0f;
  std::vector<ReliefWindow> out;
  ReliefWindow forehead{{0.5f * (lm[19].x() + lm[24].x()), brow_top + 19.0f},
                        {1.0f, 0.0f},
                        -half_width,
                        half_width,
                        -12.0f,
                        12.0f,
                        3.0f,
                        {}};
  // Crow's feet: from 3 mm outside each outer eye corner (36: subject's right, model -X).
  std::vector<ReliefWindow> eyes;
  for (const int l : {36, 45}) {
    const float out_x = l == 36 ? -1.0f : 1.0f;
    eyes.push_back({lm[l].head<2>() + Eigen::Vector2f(3.0f * out_x, 0.0f),
                    {out_x, 0.0f},
                    0.0f,
                    18.0f,
                    -10.0f,
                    10.0f,
                    3.0f,
                    {}});
  }
  if (o.relief == WrinkleRelief::kNone) {
    return out;
  } else if (o.relief == WrinkleRelief::kGrooves) {
    // Four forehead lines 6 mm apart, 0.2-1.0 mm deep (order from the seed), gently waving.
    std::array<float, 4> depth = {0.2f, 0.45f, 0.7f, 1.0f};
    for (int i = 3; i > 0; --i)
      std::swap(depth[static_cast<std::size_t>(i)],
                depth[mix64(o.seed * 31 + static_cast<std::uint64_t>(i)) % (i + 1)]);
    forehead.height = [depth](float u, float v) {
      float h = 0.0f;
      for (int k = 0; k < 4; ++k)
        h += groove(v - (-9.0f + 6.0f * k) - 1.2f * std::sin(u / 14.0f + k), depth[k], 0.9f);
      return h;
    };
    for (auto& e : eyes)
      e.height = [](float u, float v) {
        float h = 0.0f;
        const float angle[3] = {-0.5f, 0.0f, 0.5f}, dep[3] = {0.3f, 0.5f, 0.4f};
        for (int k = 0; k < 3; ++k) {
          const float c = std::cos(angle[k]), s = std::sin(angle[k]);
          const float along = u * c + v * s, across = -u * s + v * c;
          h += groove(across, dep[k], 0.8f) * smoothstep(2.0f, 5.0f, along) *
               (1.0f - smoothstep(14.0f, 18.0f, along));
        }
        return h;
      };
  } else {
    const WrinkleExemplar* f = find_crop(o, "forehead_0");
    const WrinkleExemplar* r = find_crop(o, "crows_feet_right_0");
    const WrinkleExemplar* l = find_crop(o, "crows_feet_left_0");
    if (!f || !r || !l)
      return fail(
          "the scan case needs the exemplar crops forehead_0, crows_feet_right_0 and "
          "crows_feet_left_0 (data/wrinkle_exemplars)");
    forehead.height = crop_relief(f->height_mm, o.scan_mm_per_px, 0.0f, 0.0f);
    eyes[0].height = crop_relief(r->height_mm, o.scan_mm_per_px, 9.0f, 0.0f);
    eyes[1].height = crop_relief(l->height_mm, o.scan_mm_per_px, 9.0f, 0.0f);
  }
  out.push_back(std::move(forehead));
  for (auto& e : eyes) out.push_back(std::move(e));
  return out;
}

double gaussian(std::uint64_t seed, std::uint64_t i) {
  const double u = ((mix64(seed ^ (2 * i)) >> 11) + 0.5) * 0x1.0p-53;
  const double v = (mix64(seed ^ (2 * i + 1)) >> 11) * 0x1.0p-53;
  return std::sqrt(-2.0 * std::log(u)) * std::cos(2.0 * M_PI * v);
}

std::vector<Eigen::Vector3f> vertex_normals_of(std::span<const Eigen::Vector3f> v,
                                               std::span<const std::uint32_t> t) {
  std::vector<Eigen::Vector3f> n(v.size(), Eigen::Vector3f::Zero());
  for (std::size_t i = 0; i + 2 < t.size(); i += 3) {
    const Eigen::Vector3f f = (v[t[i + 1]] - v[t[i]]).cross(v[t[i + 2]] - v[t[i]]);
    for (int k = 0; k < 3; ++k) n[t[i + k]] += f;
  }
  for (auto& x : n) x.normalize();
  return n;
}

// The synthetic camera's subject: static, frontal, textured skin, brows raised.
Result<SyntheticOptions> camera_options(const FaceModel& model, const WrinkleCaseOptions& o) {
  SyntheticOptions so;
  so.seed = o.seed;
  so.motion = SyntheticMotion::kStatic;
  so.frame_count = 1;
  so.sensor.depth_noise = false;
  so.world.seed = o.seed;
  so.world.texture = true;
  so.world.light_vary = o.light_vary;
  so.distance_mm = o.distance_mm;
  if (o.raised_brows) {
    auto brows = parse_expression_spec(
        "browInnerUp_L+browInnerUp_R+browOuterUp_L:0.8+browOuterUp_R:0.8", model);
    if (!brows) return brows.failure();
    so.expression_weights = *brows;
  }
  return so;
}

}  // namespace

Result<WrinkleCase> make_wrinkle_case(const FaceModel& model, const WrinkleCaseOptions& o) {
  auto options = camera_options(model, o);
  if (!options) return options.failure();
  const SyntheticOptions& so = *options;
  auto camera = make_synthetic_camera(model, so);
  if (!camera) return camera.failure();
  if (auto ok = (*camera)->start(); !ok) return ok.failure();
  RgbdFrame frame;
  if (auto st = (*camera)->next_frame(frame, std::chrono::milliseconds(0)); !st)
    return st.failure();
  const SyntheticCamera& cam = **camera;
  const FrameTruth& truth = *cam.truth();
  const auto verts = cam.model_vertices();
  const auto tris = cam.model_triangles();
  std::vector<Eigen::Vector3f> lm(68);
  for (int l = 0; l < 68; ++l) lm[l] = verts[model.landmark_vertices[l]];
  auto windows = relief_windows(lm, o);
  if (!windows) return windows.failure();

  WrinkleCase c;
  c.intrinsics = so.calibration.depth_intrinsics();
  for (int l = 0; l < 68; ++l) c.landmarks[l] = truth.landmarks_depth_px[l];
  for (const auto& p : truth.landmarks_3d) c.face_depth_mm += p.z() / 68.0;
  for (int l = 0; l < 68; ++l) c.landmarks_3d[l] = truth.landmarks_3d[l];
  c.camera_from_model = truth.camera_from_model;
  // The skin only (the camera's scene may hold more): the model's topology, its UV layout.
  for (int v = 0; v < model.vertex_count; ++v)
    for (int a = 0; a < 3; ++a) c.vertices.push_back(verts[static_cast<std::size_t>(v)][a]);
  PinholeIntrinsics k = c.intrinsics;
  k.width *= kSuper, k.height *= kSuper, k.fx *= kSuper, k.fy *= kSuper;
  k.cx = kSuper * k.cx + (kSuper - 1) / 2.0, k.cy = kSuper * k.cy + (kSuper - 1) / 2.0;
  std::vector<Eigen::Vector3f> posed(verts.size());
  for (std::size_t v = 0; v < verts.size(); ++v)
    posed[v] = truth.camera_from_model.apply(verts[v].cast<double>()).cast<float>();
  RasterBuffers raster;
  raster.reset(k.width, k.height);
  if (auto ok = rasterize(k, posed, tris, {}, raster); !ok) return ok.failure();
  const std::vector<Eigen::Vector3f> normals = vertex_normals_of(verts, tris);
  const WorldLight light = world_light(so.world, 0);
  const Eigen::Vector3f to_light =
      (truth.camera_from_model.rotation.conjugate().cast<float>() * light.to_light).normalized();

  const int w = c.intrinsics.width, h = c.intrinsics.height;
  c.color.resize(w, h);
  c.luminance.resize(w, h);
  c.true_height_mm.resize(w, h);
  std::vector<Eigen::Vector4i> boxes(windows->size(), Eigen::Vector4i(w, h, -1, -1));
  const Eigen::Vector3f wall(so.wall_color.r, so.wall_color.g, so.wall_color.b);
  auto relief = [&](const Eigen::Vector2f& p, std::vector<bool>* inside) {
    float z = 0.0f;
    for (std::size_t i = 0; i < windows->size(); ++i) {
      const ReliefWindow& win = (*windows)[i];
      const Eigen::Vector2f uv = win.local(p);
      const float wt = win.weight(uv);
      if (wt <= 0.0f) continue;
      z += wt * win.height(uv.x(), uv.y());
      if (inside) (*inside)[i] = true;
    }
    return z;
  };
  std::vector<bool> inside(windows->size());
  // The neutral is another exposure: its own noise (the raised-brow cases keep theirs).
  const std::uint64_t noise_seed = mix64(o.seed ^ 0x3c0104) + (o.raised_brows ? 0 : 0x5e11);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      Eigen::Vector3f sum = Eigen::Vector3f::Zero();
      float height_sum = 0.0f;
      std::fill(inside.begin(), inside.end(), false);
      for (int j = 0; j < kSuper; ++j)
        for (int i = 0; i < kSuper; ++i) {
          const std::size_t s = raster.index(kSuper * x + i, kSuper * y + j);
          const std::int32_t t = raster.triangle[s];
          if (t == kNoTriangle) {
            sum += wall;
            continue;
          }
          const float b1 = raster.bary1[s], b2 = raster.bary2[s], b0 = 1.0f - b1 - b2;
          const auto a = tris[3 * t], b = tris[3 * t + 1], cc = tris[3 * t + 2];
          const Eigen::Vector3f p = b0 * verts[a] + b1 * verts[b] + b2 * verts[cc];
          Eigen::Vector3f n = (b0 * normals[a] + b1 * normals[b] + b2 * normals[cc]).normalized();
          const Eigen::Vector2f q = p.head<2>();
          const float z = relief(q, &inside);
          if (z != 0.0f) {
            // The relief's slope on the surface: its (x, y) gradient projected onto the
            // tangent plane tilts the normal.
            const float d = 0.05f;
            const Eigen::Vector3f g((relief(q + Eigen::Vector2f(d, 0), nullptr) -
                                     relief(q - Eigen::Vector2f(d, 0), nullptr)) /
                                        (2 * d),
                                    (relief(q + Eigen::Vector2f(0, d), nullptr) -
                                     relief(q - Eigen::Vector2f(0, d), nullptr)) /
                                        (2 * d),
                                    0.0f);
            n = (n - (g - n * n.dot(g))).normalized();
          }
          height_sum += z;
          const float intensity = light.ambient + light.diffuse * std::max(0.0f, n.dot(to_light));
          sum += (cam.surface_albedo(t, b1, b2) * intensity * 255.0f).cwiseProduct(light.tint);
        }
      constexpr float kSamples = kSuper * kSuper;
      c.true_height_mm.at(x, y) = height_sum / kSamples;
      for (std::size_t i = 0; i < inside.size(); ++i)
        if (inside[i])
          boxes[i] = {std::min(boxes[i][0], x), std::min(boxes[i][1], y), std::max(boxes[i][2], x),
                      std::max(boxes[i][3], y)};
      const std::size_t idx = static_cast<std::size_t>(y) * w + x;
      std::uint8_t ch[3];
      for (int k3 = 0; k3 < 3; ++k3)
        ch[k3] = static_cast<std::uint8_t>(std::clamp(
            sum[k3] / kSamples + 3.0 * gaussian(noise_seed, 3 * idx + k3) + 0.5, 0.0, 255.0));
      c.color.at(x, y) = {ch[0], ch[1], ch[2]};
      c.luminance.at(x, y) = (0.299f * ch[0] + 0.587f * ch[1] + 0.114f * ch[2]) / 255.0f;
    }
  for (const auto& b : boxes)
    if (b[2] >= b[0])
      c.true_regions.push_back(PixelRect::from_size(b[0], b[1], b[2] - b[0] + 1, b[3] - b[1] + 1));
  return c;
}

Result<WrinkleCase> make_neutral_case(const FaceModel& model, WrinkleCaseOptions options) {
  options.relief = WrinkleRelief::kNone;
  options.raised_brows = false;
  return make_wrinkle_case(model, options);
}

std::vector<Eigen::Vector3f> camera_vertices(const WrinkleCase& c) {
  std::vector<Eigen::Vector3f> out(c.vertices.size() / 3);
  for (std::size_t v = 0; v < out.size(); ++v)
    out[v] =
        c.camera_from_model
            .apply(Eigen::Vector3d(c.vertices[3 * v], c.vertices[3 * v + 1], c.vertices[3 * v + 2]))
            .cast<float>();
  return out;
}

CaseFace::CaseFace(const WrinkleCase& c, const FaceModel& model, const WrinkleCase* n)
    : expression(camera_vertices(c)) {
  face.intrinsics = c.intrinsics;
  face.expression = {expression, model.triangles};
  if (n == nullptr) return;
  neutral = camera_vertices(*n);
  face.neutral = {neutral, model.triangles};
  face.neutral_luminance = &n->luminance;
}

Result<RgbdFrame> wrinkle_case_frame(const WrinkleCase& c, const FaceModel& model,
                                     const KinectRegistration& registration) {
  const PinholeIntrinsics k = c.intrinsics;
  const std::vector<Eigen::Vector3f> posed = camera_vertices(c);
  PinholeIntrinsics ks = k;
  ks.width *= kSuper, ks.height *= kSuper, ks.fx *= kSuper, ks.fy *= kSuper;
  ks.cx = kSuper * k.cx + (kSuper - 1) / 2.0, ks.cy = kSuper * k.cy + (kSuper - 1) / 2.0;
  RasterBuffers raster;
  raster.reset(ks.width, ks.height);
  if (auto ok = rasterize(ks, posed, model.triangles, {}, raster); !ok) return ok.failure();
  RgbdFrame f;
  f.depth_mm.resize(k.width, k.height);
  std::fill(f.depth_mm.pixels.begin(), f.depth_mm.pixels.end(), std::uint16_t{0});
  f.color = c.color;  // off the face: the unregistered frame (the wall is flat colour anyway)
  std::vector<float> zbuf(f.color.pixels.size(), std::numeric_limits<float>::infinity());
  std::vector<std::uint8_t> hit(f.color.pixels.size(), 0);
  auto sample = [&](double x, double y) {
    x = std::clamp(x, 0.0, c.color.width - 1.001);
    y = std::clamp(y, 0.0, c.color.height - 1.001);
    const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
    const double ax = x - x0, ay = y - y0;
    Rgb8 out;
    std::uint8_t* o[3] = {&out.r, &out.g, &out.b};
    for (int ch = 0; ch < 3; ++ch) {
      auto v = [&](int px, int py) {
        const Rgb8 p = c.color.at(px, py);
        return ch == 0 ? p.r : ch == 1 ? p.g : p.b;
      };
      *o[ch] = static_cast<std::uint8_t>(
          std::lround((1 - ay) * ((1 - ax) * v(x0, y0) + ax * v(x0 + 1, y0)) +
                      ay * ((1 - ax) * v(x0, y0 + 1) + ax * v(x0 + 1, y0 + 1))));
    }
    return out;
  };
  for (int y = 0; y < ks.height; ++y)
    for (int x = 0; x < ks.width; ++x) {
      const std::size_t i = raster.index(x, y);
      if (raster.triangle[i] == kNoTriangle) continue;
      const float z = raster.depth[i];
      const double dx = (x - (kSuper - 1) / 2.0) / kSuper, dy = (y - (kSuper - 1) / 2.0) / kSuper;
      if (x % kSuper == 1 && y % kSuper == 1)
        f.depth_mm.at(x / kSuper, y / kSuper) = static_cast<std::uint16_t>(std::lround(z));
      double cx = 0.0, cy = 0.0;
      if (!registration.depth_to_color_interpolated(dx, dy, std::round(z), cx, cy)) continue;
      const int px = static_cast<int>(std::lround(cx)), py = static_cast<int>(std::lround(cy));
      if (px < 0 || py < 0 || px >= f.color.width || py >= f.color.height) continue;
      const std::size_t j = static_cast<std::size_t>(py) * f.color.width + px;
      if (z >= zbuf[j]) continue;
      zbuf[j] = z;
      hit[j] = 1;
      f.color.pixels[j] = sample(dx, dy);
    }
  // Colour pixels inside the face no sub-sample landed on: the nearest hit along the row.
  for (int y = 0; y < f.color.height; ++y)
    for (int x = 1; x + 1 < f.color.width; ++x) {
      const std::size_t j = static_cast<std::size_t>(y) * f.color.width + x;
      if (!hit[j] && hit[j - 1] && hit[j + 1]) f.color.pixels[j] = f.color.pixels[j - 1];
    }
  return f;
}

WrinkleScore score_wrinkles(const WrinkleCase& c, const WrinkleDetail& d, int margin) {
  const int w = c.luminance.width, h = c.luminance.height;
  auto in_any = [](const std::vector<PixelRect>& rs, int x, int y, int grow) {
    for (const auto& r : rs)
      if (x >= r.x0 - grow && y >= r.y0 - grow && x < r.x1 + grow && y < r.y1 + grow) return true;
    return false;
  };
  WrinkleScore s;
  double t_n = 0, w_n = 0, w_hit = 0, d_n = 0, d_in = 0;
  double sg = 0, st = 0, sgg = 0, stt = 0, sgt = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const float truth = c.true_height_mm.at(x, y), got = d.synthesis.height_mm.at(x, y);
      const bool t = in_any(c.true_regions, x, y, 0), t5 = in_any(c.true_regions, x, y, margin);
      const bool det = d.synthesis.domain.at(x, y) != 0;
      if (t) {
        ++t_n;
        s.height_mae_mm += std::abs(got - truth);
        s.zero_field_mae_mm += std::abs(truth);
        sg += got, st += truth, sgg += got * got, stt += truth * truth, sgt += got * truth;
        if (std::abs(truth) >= 0.1f) {
          ++w_n;
          w_hit += det;
          s.wrinkle_pixel_mae_mm += std::abs(got - truth);
        }
      }
      if (det) ++d_n, d_in += t5;
      if (!t5 && std::abs(got) > s.max_displacement_outside_mm) {
        s.max_displacement_outside_mm = std::abs(got);
        s.max_outside_x = x, s.max_outside_y = y;
      }
    }
  if (t_n > 1) {
    const double cov = sgt - sg * st / t_n, vg = sgg - sg * sg / t_n, vt = stt - st * st / t_n;
    s.height_correlation = vg > 0 && vt > 0 ? cov / std::sqrt(vg * vt) : 0.0;
  }
  s.height_mae_mm /= std::max(1.0, t_n);
  s.zero_field_mae_mm /= std::max(1.0, t_n);
  s.wrinkle_pixel_mae_mm /= std::max(1.0, w_n);
  s.region_recall = w_n > 0 ? w_hit / w_n : 0.0;
  s.region_precision = d_n > 0 ? d_in / d_n : 0.0;
  return s;
}

}  // namespace fb::cli
