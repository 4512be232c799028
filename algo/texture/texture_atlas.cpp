#include "algo/texture/texture_atlas.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include <Eigen/Dense>

#include "algo/render/rasterizer.hpp"
#include "algo/texture/atlas_fill.hpp"

namespace fb {

namespace {

struct Texel {
  std::uint32_t index = 0;  // in the atlas
  Eigen::Vector3f p, n;     // model frame
};

struct Sample {
  Eigen::Vector3f color;
  Eigen::Vector3f normal;  // camera frame
  float weight = 0.0f;
  bool clipped = false;
};

Eigen::Vector3f bilinear(const ColorImage& image, double x, double y) {
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  const float ax = static_cast<float>(x - x0), ay = static_cast<float>(y - y0);
  auto at = [&](int u, int v) {
    const Rgb8 c = image.at(std::clamp(u, 0, image.width - 1), std::clamp(v, 0, image.height - 1));
    return Eigen::Vector3f(c.r, c.g, c.b);
  };
  return (1 - ay) * ((1 - ax) * at(x0, y0) + ax * at(x0 + 1, y0)) +
         ay * ((1 - ax) * at(x0, y0 + 1) + ax * at(x0 + 1, y0 + 1));
}

// One view prepared for sampling: the mesh posed and rasterised into the depth camera.
class ViewSampler {
 public:
  ViewSampler(const TextureMesh& mesh, const KinectRegistration& registration,
              const TextureOptions& options)
      : mesh_(mesh),
        registration_(registration),
        options_(options),
        intrinsics_(registration.depth_intrinsics()) {}

  Result<void> prepare(const TextureView& view) {
    view_ = &view;
    rotation_ = view.camera_from_model.rotation.toRotationMatrix().cast<float>();
    translation_ = view.camera_from_model.translation.cast<float>();
    const std::size_t n = mesh_.vertices.size() / 3;
    std::vector<Eigen::Vector3f> posed(n);
    for (std::size_t v = 0; v < n; ++v)
      posed[v] = rotation_ * Eigen::Vector3f(mesh_.vertices[3 * v], mesh_.vertices[3 * v + 1],
                                             mesh_.vertices[3 * v + 2]) +
                 translation_;
    RasterBuffers raster;
    raster.reset(intrinsics_.width, intrinsics_.height);
    RasterOptions ro;
    ro.cull_backfaces = false;  // the z-buffer must hold whatever is nearest
    if (auto ok = rasterize(intrinsics_, posed, mesh_.triangles, ro, raster); !ok) return ok;
    zbuffer_ = std::move(raster.depth);  // all sampling needs; the rest is freed
    return {};
  }

  bool sample(const Texel& t, Sample& out) const {
    const Eigen::Vector3f p = rotation_ * t.p + translation_;
    if (p.z() <= 0.0f) return false;
    const Eigen::Vector3f n = rotation_ * t.n;
    const float facing = n.dot(-p.normalized());
    if (facing < options_.min_facing) return false;
    const Eigen::Vector2d px = intrinsics_.project(p.cast<double>());
    const int x = static_cast<int>(std::lround(px.x())), y = static_cast<int>(std::lround(px.y()));
    if (x < 0 || y < 0 || x >= intrinsics_.width || y >= intrinsics_.height) return false;
    const std::size_t pixel = static_cast<std::size_t>(y) * intrinsics_.width + x;
    if (!(p.z() <= zbuffer_[pixel] + options_.visibility_mm)) return false;
    if (view_->depth != nullptr && view_->depth->contains(x, y)) {
      // The sensor must see this surface there: something nearer is an occluder (a hand),
      // something farther or nothing means the true silhouette is not where the mesh's is
      // (the colour there is the wall), as at the grazing edges of the head.
      const float measured = view_->depth->at(x, y);
      if (!(std::abs(measured - p.z()) <= options_.occluder_mm)) return false;
    }
    double cx = 0.0, cy = 0.0;
    if (!registration_.depth_to_color_interpolated(px.x(), px.y(), p.z(), cx, cy)) return false;
    const ColorImage& color = *view_->color;
    if (cx < 0.0 || cy < 0.0 || cx > color.width - 1.0 || cy > color.height - 1.0) return false;
    const float w = (facing - options_.min_facing) / (1.0f - options_.min_facing);
    out.color = bilinear(color, cx, cy);
    out.normal = n;
    // A clipped channel is not the surface's colour: such a sample counts only where no view
    // saw the texel unclipped (bright skin facing the light clips red first).
    out.clipped = out.color.maxCoeff() >= options_.clip_level;
    const float wp = options_.weight_power == 2.0f ? w * w : std::pow(w, options_.weight_power);
    out.weight = wp * (out.clipped ? 1e-3f : 1.0f);
    return true;
  }

 private:
  const TextureMesh& mesh_;
  const KinectRegistration& registration_;
  const TextureOptions& options_;
  PinholeIntrinsics intrinsics_;
  const TextureView* view_ = nullptr;
  Eigen::Matrix3f rotation_;
  Eigen::Vector3f translation_;
  std::vector<float> zbuffer_;  // the posed mesh's nearest depth per depth pixel
};

using Lighting = std::array<Eigen::Vector4f, 3>;

// Ambient plus a clamped Lambertian key light: l0 + max(0, l . n). The clamp matters: under the
// nose and the chin the face turns away from the light and only the ambient part is left.
float shading(const Eigen::Vector4f& l, const Eigen::Vector3f& n) {
  return std::max(0.05f, l[0] + std::max(0.0f, l.tail<3>().dot(n)));
}

struct Observation {
  std::uint32_t texel = 0;  // position in the lighting subset
  std::uint32_t view = 0;
  Sample s;
};

// Per-view lighting (ambient + clamped key light per channel) fitted with the skin taken as one
// colour: with per-texel albedo free as well, the albedo absorbs whatever shading the head
// turn does not vary (a yaw turn hardly changes how much a texel faces up), so the light's
// vertical part would stay in the texture. Features that differ from the skin colour (brows,
// lips, eyes, hair) are down-weighted as outliers (Cauchy on the relative residual).
std::vector<Lighting> estimate_lighting(const std::vector<Observation>& obs, std::size_t views,
                                        int iterations) {
  Lighting unit;
  unit.fill(Eigen::Vector4f(1.0f, 0.0f, 0.0f, 0.0f));
  std::vector<Lighting> lighting(views, unit);
  // The skin colour: the weighted median-ish start is the mean; the robust weights refine it.
  Eigen::Vector3d skin = Eigen::Vector3d::Zero();
  double total = 0.0;
  for (const auto& o : obs) {
    skin += o.s.weight * o.s.color.cast<double>();
    total += o.s.weight;
  }
  if (total <= 0.0) return lighting;
  skin /= total;
  constexpr double kScale = 0.1;  // relative residual at which a sample's weight halves
  for (int it = 0; it < iterations; ++it) {
    std::vector<std::array<Eigen::Matrix4d, 3>> a(views);
    std::vector<std::array<Eigen::Vector4d, 3>> b(views);
    std::vector<int> count(views, 0);
    for (auto& m : a) m.fill(Eigen::Matrix4d::Zero());
    for (auto& v : b) v.fill(Eigen::Vector4d::Zero());
    Eigen::Vector3d skin_num = Eigen::Vector3d::Zero(), skin_den = Eigen::Vector3d::Zero();
    for (const auto& o : obs) {
      ++count[o.view];
      for (int c = 0; c < 3; ++c) {
        const Eigen::Vector4f& l = lighting[o.view][c];
        const double s = shading(l, o.s.normal);
        const double r = (o.s.color[c] - skin[c] * s) / std::max(1.0, skin[c] * s);
        const double w = it == 0 ? o.s.weight : o.s.weight / (1.0 + (r / kScale) * (r / kScale));
        // Linear in the light for the normals it reaches (all of them on the first round,
        // before its direction is known): the clamp's active set, re-estimated each round.
        const bool lit = it == 0 || l.tail<3>().dot(o.s.normal) > 0.0f;
        const Eigen::Vector3d n =
            lit ? Eigen::Vector3d(o.s.normal.cast<double>()) : Eigen::Vector3d::Zero();
        const Eigen::Vector4d j = skin[c] * Eigen::Vector4d(1.0, n.x(), n.y(), n.z());
        a[o.view][c] += w * j * j.transpose();
        b[o.view][c] += w * o.s.color[c] * j;
        skin_num[c] += w * o.s.color[c] * s;
        skin_den[c] += w * s * s;
      }
    }
    for (std::size_t v = 0; v < views; ++v) {
      if (count[v] < 50) continue;  // too few texels to tell its light: keep the last estimate
      for (int c = 0; c < 3; ++c) {
        const Eigen::Vector4d l = a[v][c].ldlt().solve(b[v][c]);
        if (l.allFinite()) lighting[v][c] = l.cast<float>();
      }
    }
    if (it > 0)
      for (int c = 0; c < 3; ++c)
        if (skin_den[c] > 0) skin[c] = skin_num[c] / skin_den[c];
  }
  // Absolute albedo is unobservable (exposure, white balance): keep the frames' mean level.
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double weight = 0.0;
  for (const auto& o : obs) {
    for (int c = 0; c < 3; ++c) sum[c] += o.s.weight * shading(lighting[o.view][c], o.s.normal);
    weight += o.s.weight;
  }
  if (weight > 0.0)
    for (auto& l : lighting)
      for (int c = 0; c < 3; ++c)
        if (sum[c] > 0.0) l[c] /= static_cast<float>(sum[c] / weight);
  return lighting;
}

}  // namespace

Result<TextureAtlas> build_texture_atlas(const TexelMap& map, const TextureMesh& mesh,
                                         std::span<const TextureView> views,
                                         const KinectRegistration& registration,
                                         const TextureOptions& options) {
  if (views.empty()) return fail("no colour frames to build a texture from");
  if (mesh.normals.size() != mesh.vertices.size())
    return fail("the mesh's normals do not match its vertices");
  for (const auto& v : views)
    if (v.color == nullptr || v.color->empty())
      return fail("a frame without a colour image; the texture needs the take's colour frames");
  // The covered texels' surface points and normals in the model frame.
  std::vector<Texel> texels;
  texels.reserve(static_cast<std::size_t>(map.covered));
  for (std::size_t i = 0; i < map.triangle.size(); ++i) {
    if (map.triangle[i] < 0) continue;
    const auto t = static_cast<std::size_t>(map.triangle[i]);
    if (3 * t + 2 >= mesh.triangles.size())
      return fail("the UV layout has more triangles than the mesh");
    Texel x;
    x.index = static_cast<std::uint32_t>(i);
    x.p = texel_point(map, i, mesh.triangles, mesh.vertices);
    x.n = texel_point(map, i, mesh.triangles, mesh.normals).normalized();
    texels.push_back(x);
  }
  // Every view posed and rasterised once; the texels are then visited once each, all views
  // together (texel-major: the texel's data and its sums stay in cache across the views).
  std::vector<ViewSampler> samplers;
  samplers.reserve(views.size());
  for (const auto& view : views) {
    samplers.emplace_back(mesh, registration, options);
    if (auto ok = samplers.back().prepare(view); !ok) return ok.failure();
  }
  TextureAtlas out;
  out.report.views = static_cast<int>(views.size());
  out.report.covered_texels = static_cast<int>(texels.size());

  // Lighting from a subset of texels.
  Lighting unit;
  unit.fill(Eigen::Vector4f(1.0f, 0.0f, 0.0f, 0.0f));
  std::vector<Lighting> lighting(views.size(), unit);
  if (options.delight) {
    std::vector<std::uint32_t> subset;
    const int stride = std::max(1, options.lighting_stride);
    for (std::uint32_t k = 0; k < texels.size(); ++k) {
      const int x = static_cast<int>(texels[k].index % map.width),
                y = static_cast<int>(texels[k].index / map.width);
      if (x % stride == 0 && y % stride == 0) subset.push_back(k);
    }
    std::vector<Observation> obs;
    for (std::uint32_t v = 0; v < views.size(); ++v) {
      Sample s;
      for (std::uint32_t k = 0; k < subset.size(); ++k)
        if (samplers[v].sample(texels[subset[k]], s) && !s.clipped) obs.push_back({k, v, s});
    }
    lighting = estimate_lighting(obs, views.size(), options.lighting_iterations);
  }
  out.report.lighting = lighting;

  // Every texel from every view, the lighting divided out.
  std::vector<Eigen::Vector3f> num(texels.size(), Eigen::Vector3f::Zero()), den = num;
  std::vector<float> weight(texels.size(), 0.0f);
  std::vector<std::uint8_t> unclipped(texels.size(), 0);
  for (std::size_t k = 0; k < texels.size(); ++k) {
    Sample s;
    for (std::size_t v = 0; v < views.size(); ++v) {
      if (!samplers[v].sample(texels[k], s)) continue;
      for (int c = 0; c < 3; ++c) {
        const float sh = shading(lighting[v][c], s.normal);
        num[k][c] += s.weight * s.color[c] * sh;
        den[k][c] += s.weight * sh * sh;
      }
      weight[k] += s.weight;
      unclipped[k] |= !s.clipped;
    }
  }
  Image<Eigen::Vector3f> albedo;
  albedo.resize(map.width, map.height);
  std::fill(albedo.pixels.begin(), albedo.pixels.end(), Eigen::Vector3f::Zero());
  out.weight.resize(map.width, map.height);
  std::fill(out.weight.pixels.begin(), out.weight.pixels.end(), 0.0f);
  out.clipped.resize(map.width, map.height);
  std::fill(out.clipped.pixels.begin(), out.clipped.pixels.end(), std::uint8_t{0});
  for (std::size_t k = 0; k < texels.size(); ++k) {
    if (!(weight[k] > 0.0f)) continue;
    ++out.report.observed_texels;
    out.weight.pixels[texels[k].index] = weight[k];
    if (!unclipped[k]) {
      out.clipped.pixels[texels[k].index] = 1;
      ++out.report.clipped_texels;
    }
    for (int c = 0; c < 3; ++c)
      albedo.pixels[texels[k].index][c] = den[k][c] > 0 ? num[k][c] / den[k][c] : 0.0f;
  }
  if (out.report.observed_texels == 0)
    return fail(
        "no frame shows the face where the mesh is; check that the mesh belongs to this "
        "take and the unit's calibration");
  Image<float> known = out.weight;
  mesh_fill(albedo, known, map, mesh.triangles, mesh.vertices.size() / 3);
  push_pull_fill(albedo, known);
  out.image.resize(map.width, map.height);
  for (std::size_t i = 0; i < albedo.pixels.size(); ++i) {
    const Eigen::Vector3f c = albedo.pixels[i].cwiseMax(0.0f).cwiseMin(255.0f);
    out.image.pixels[i] =
        Rgb8{static_cast<std::uint8_t>(c.x() + 0.5f), static_cast<std::uint8_t>(c.y() + 0.5f),
             static_cast<std::uint8_t>(c.z() + 0.5f)};
  }
  return out;
}

}  // namespace fb
