#include "sim/lab/wrinkle_tracking_bench.hpp"

#include <algorithm>
#include <chrono>

#include "algo/core/clock.hpp"
#include "algo/core/mix64.hpp"
#include "algo/texture/texel_map.hpp"
#include "algo/wrinkles/capture_detail.hpp"
#include "algo/wrinkles/detail_blend.hpp"
#include "algo/wrinkles/wrinkle_geometry.hpp"

namespace fb::cli {

namespace {

// The peer: the same E = N + sum_e c_e (D_e - N) over every texel of the full maps.
struct DenseBlend {
  std::vector<float> neutral;              // 3 per texel
  std::vector<std::vector<float>> deltas;  // per capture, 3 per texel
  void apply(const DetailBlend& b, std::span<const float> weights, std::vector<float>& c,
             std::vector<float>& acc, BlendedDetail& out) const {
    const std::size_t ne = deltas.size();
    std::fill(c.begin(), c.end(), 0.0f);
    for (std::size_t s = 0; s < weights.size() && s < static_cast<std::size_t>(b.shape_count());
         ++s)
      for (std::size_t e = 0; e < ne; ++e)
        c[e] += weights[s] * b.coefficient(static_cast<int>(s), static_cast<int>(e));
    std::copy(neutral.begin(), neutral.end(), acc.begin());
    for (std::size_t e = 0; e < ne; ++e) {
      if (c[e] == 0.0f) continue;
      const float* src = deltas[e].data();
      for (std::size_t i = 0; i < acc.size(); ++i) acc[i] += c[e] * src[i];
    }
    for (std::size_t t = 0; t < out.displacement_mm.pixels.size(); ++t) {
      out.displacement_mm.pixels[t] = acc[3 * t];
      out.normal_map.pixels[t] = DetailBlend::normal_byte(acc[3 * t + 1], acc[3 * t + 2]);
    }
  }
};

}  // namespace

Result<nlohmann::json> bench_detail_blend(const FaceModel& model, const GuideSet& guide,
                                          const WrinkleCase& c, const WrinkleDetail& detail,
                                          int map_height, int frames) {
  const std::vector<float> uvs = model.atlas_uvs();
  auto map = make_texel_map(uvs, model.triangle_uvs, map_height * model.uv_tiles(), map_height);
  if (!map) return map.failure();
  FloatImage feathered = detail.synthesis.height_mm;  // as capture_detail stores it
  feather_heights(feathered, detail.synthesis.domain, CaptureDetailOptions{}.feather_px);
  HeightView view;
  view.height_mm = &feathered;
  view.domain = &detail.synthesis.domain;
  view.camera_from_model = c.camera_from_model;
  view.intrinsics = c.intrinsics;
  auto maps = detail_maps(*map, uvs, model.triangle_uvs, c.vertices, model.triangles, view);
  if (!maps) return maps.failure();
  // The neutral flat; every guide expression carries the case's detail, scaled 0.5-1.0 (the
  // worst case for the blend: all 19 captures with detail, every shape moved by some).
  DetailMaps flat;
  flat.displacement_mm.resize(map->width, map->height);
  std::fill(flat.displacement_mm.pixels.begin(), flat.displacement_mm.pixels.end(), 0.0f);
  flat.normal_map.resize(map->width, map->height);
  std::fill(flat.normal_map.pixels.begin(), flat.normal_map.pixels.end(), Rgb8{128, 128, 255});
  std::vector<DetailMaps> layers;
  std::vector<std::vector<float>> recipes;
  for (std::size_t g = 1; g < guide.expressions.size(); ++g) {
    auto w = guide_weights(guide.expressions[g], model);
    if (!w) return w.failure();
    w->resize(static_cast<std::size_t>(model.fitting_expression_count));
    recipes.push_back(std::move(*w));
    DetailMaps m = *maps;
    const float k = 0.5f + 0.5f * static_cast<float>(g) / guide.expressions.size();
    for (auto& h : m.displacement_mm.pixels) h *= k;
    layers.push_back(std::move(m));
  }
  std::vector<DetailLayerView> views;
  for (const auto& l : layers) views.push_back({&l.displacement_mm, &l.normal_map});
  auto blend = DetailBlend::build({&flat.displacement_mm, &flat.normal_map}, views, recipes,
                                  model.fitting_expression_count);
  if (!blend) return blend.failure();

  // Per frame weights: every shape active, a deterministic draw in [0, 1).
  const int ns = model.fitting_expression_count;
  std::vector<float> weights(static_cast<std::size_t>(frames) * ns);
  for (std::size_t i = 0; i < weights.size(); ++i)
    weights[i] = static_cast<float>((mix64(0x5eed + i) >> 11) * 0x1.0p-53);
  auto frame = [&](int f) {
    return std::span<const float>(weights).subspan(static_cast<std::size_t>(f) * ns, ns);
  };
  BlendedDetail ours;
  blend->prepare(ours);
  auto t0 = Clock::now();
  for (int f = 0; f < frames; ++f) blend->apply(frame(f), ours);
  const double ours_ms = ms_since(t0) / frames;
  std::vector<float> streamed(views.size());
  double checksum = 0.0;
  t0 = Clock::now();
  for (int f = 0; f < frames; ++f) {
    blend->map_weights(frame(f), streamed);
    checksum += streamed[0];
  }
  const double weights_ms = ms_since(t0) / frames;
  // All weights 0: no layer is blended, only the neutral copied and the maps written.
  const std::vector<float> zeros(static_cast<std::size_t>(ns), 0.0f);
  t0 = Clock::now();
  for (int f = 0; f < frames; ++f) blend->apply(zeros, ours);
  const double write_ms = ms_since(t0) / frames;

  DenseBlend dense;
  const std::size_t texels = flat.displacement_mm.pixels.size();
  dense.neutral.resize(3 * texels);
  for (std::size_t t = 0; t < texels; ++t)
    DetailBlend::channels_of({&flat.displacement_mm, &flat.normal_map}, t, &dense.neutral[3 * t]);
  for (const auto& v : views) {
    std::vector<float> d(3 * texels);
    for (std::size_t t = 0; t < texels; ++t) {
      DetailBlend::channels_of(v, t, &d[3 * t]);
      for (int k = 0; k < 3; ++k) d[3 * t + k] -= dense.neutral[3 * t + k];
    }
    dense.deltas.push_back(std::move(d));
  }
  BlendedDetail full;
  blend->prepare(full);
  std::vector<float> cw(views.size()), acc(3 * texels);
  const int dense_frames = std::max(1, frames / 10);
  t0 = Clock::now();
  for (int f = 0; f < dense_frames; ++f) dense.apply(*blend, frame(f), cw, acc, full);
  const double dense_ms = ms_since(t0) / dense_frames;
  // Both give the same maps (the last dense frame against ours at that frame).
  blend->apply(frame(dense_frames - 1), ours);
  double max_diff = 0.0;
  for (std::size_t t = 0; t < texels; ++t)
    max_diff = std::max(max_diff, static_cast<double>(std::abs(ours.displacement_mm.pixels[t] -
                                                               full.displacement_mm.pixels[t])));
  return nlohmann::json{
      {"tracking_overhead_ms", ours_ms},
      {"peer", "dense: the same blend over every texel of the full-resolution maps"},
      {"peer_ms", dense_ms},
      {"speedup_vs_peer", ours_ms > 0 ? dense_ms / ours_ms : 0.0},
      {"max_difference_mm", max_diff},
      {"map_weights_ms", weights_ms},
      {"write_only_ms", write_ms},
      {"map_weights_note",
       "c = P^T a alone: what a renderer holding the captures' maps needs per frame (the "
       "blend then runs on its side): what `track --detail-weights` and `export --take` "
       "write per frame"},
      {"map_weights_checksum", checksum},
      {"map", std::to_string(map->width) + "x" + std::to_string(map->height)},
      {"support_texels", blend->support().size()},
      {"texels", texels},
      {"captures_with_detail", blend->capture_count()},
      {"shapes", ns},
      {"detailed_shapes", blend->detailed_shapes()},
      {"frames", frames},
      {"peer_frames", dense_frames},
      {"budget", "tracking_overhead_ms <= 0.3 per frame"},
      {"timed", "c = P^T a, E = N + sum c_e (D_e - N) on the maps, normal bytes written"}};
}

}  // namespace fb::cli
