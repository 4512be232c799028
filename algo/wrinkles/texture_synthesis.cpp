#include "algo/wrinkles/texture_synthesis.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "algo/core/mix64.hpp"

namespace fb {

namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

// Planar feature channels: gradients x, y and height, row-major.
struct Channels {
  int width = 0, height = 0;
  std::vector<float> gx, gy, s, h;
  std::size_t index(int x, int y) const { return static_cast<std::size_t>(y) * width + x; }
};

struct Match {
  int e = -1, x = 0, y = 0;
  float cost = kInf;
};

// A counter-based generator: deterministic per seed, no shared state.
class Random {
 public:
  explicit Random(std::uint64_t seed) : state_(seed) {}
  std::uint64_t next() { return mix64(state_ += 0x9e3779b97f4a7c15ull); }
  int below(int n) { return static_cast<int>(next() % static_cast<std::uint64_t>(n)); }

 private:
  std::uint64_t state_;
};

class Synthesizer {
 public:
  Synthesizer(const ImageGradient& input, const FloatImage& shading,
              std::span<const PixelRect> regions, std::span<const WrinkleExemplar> exemplars,
              const SynthesisOptions& o, const Image<std::uint8_t>* excluded)
      : o_(o), r_(o.patch_radius), w_(input.gx.width), h_(input.gx.height) {
    // The input padded by the patch radius (edges clamped), so patches need no bounds checks.
    in_.width = w_ + 2 * r_;
    in_.height = h_ + 2 * r_;
    const std::size_t n = static_cast<std::size_t>(in_.width) * in_.height;
    in_.gx.resize(n);
    in_.gy.resize(n);
    in_.s.resize(n);
    in_.h.assign(n, 0.0f);
    for (int y = 0; y < in_.height; ++y)
      for (int x = 0; x < in_.width; ++x) {
        const int sx = std::clamp(x - r_, 0, w_ - 1), sy = std::clamp(y - r_, 0, h_ - 1);
        in_.gx[in_.index(x, y)] = input.gx.at(sx, sy);
        in_.gy[in_.index(x, y)] = input.gy.at(sx, sy);
        in_.s[in_.index(x, y)] = shading.at(sx, sy);
      }
    domain_.resize(w_, h_);
    std::fill(domain_.pixels.begin(), domain_.pixels.end(), std::uint8_t{0});
    for (const auto& rect : regions)
      for (int y = std::max(0, rect.y0); y < std::min(h_, rect.y1); ++y)
        for (int x = std::max(0, rect.x0); x < std::min(w_, rect.x1); ++x)
          domain_.at(x, y) = excluded == nullptr || !excluded->at(x, y);
    for (int y = 0; y < h_; ++y)
      for (int x = 0; x < w_; ++x)
        if (domain_.at(x, y)) pixels_.emplace_back(x, y);
    for (const auto& e : exemplars) {
      if (e.height_mm.width <= 2 * r_ || e.height_mm.height <= 2 * r_) continue;
      const ImageGradient g = wrinkle_features(e.luminance, o);
      Channels c;
      c.width = e.height_mm.width;
      c.height = e.height_mm.height;
      c.gx = g.gx.pixels;
      c.gy = g.gy.pixels;
      c.s = normalised_shading(e.luminance, o).pixels;
      c.h = e.height_mm.pixels;
      const int centres = (c.width - 2 * r_) * (c.height - 2 * r_);
      first_centre_.push_back(total_centres_);
      total_centres_ += centres;
      ex_.push_back(std::move(c));
    }
    nnf_.assign(static_cast<std::size_t>(w_) * h_, Match{});
  }

  bool has_exemplars() const { return !ex_.empty(); }

  WrinkleSynthesis run() {
    WrinkleSynthesis out;
    out.domain = domain_;
    out.patches = static_cast<int>(pixels_.size());
    Random rng(o_.seed);
    for (int it = 0; it < o_.em_iterations; ++it) {
      lambda_ = it == 0 ? 0.0f : static_cast<float>(o_.lambda);  // no heights to match yet
      if (o_.search == PatchSearch::kBruteForce) {
        for (const auto& p : pixels_) brute_force(p.x(), p.y());
      } else {
        for (const auto& p : pixels_) {
          Match& m = nnf_[static_cast<std::size_t>(p.y()) * w_ + p.x()];
          if (m.e < 0)
            m = random_match(rng, p.x(), p.y());
          else
            m.cost = distance(p.x(), p.y(), m.e, m.x, m.y, kInf);
        }
        for (int pass = 0; pass < o_.patchmatch_passes; ++pass) patchmatch_pass(rng, pass % 2 == 0);
      }
      double e = 0.0;
      for (const auto& p : pixels_) e += nnf_[static_cast<std::size_t>(p.y()) * w_ + p.x()].cost;
      out.energy.push_back(pixels_.empty() ? 0.0 : e / static_cast<double>(pixels_.size()));
      e_step();
    }
    out.height_mm.resize(w_, h_);
    for (int y = 0; y < h_; ++y)
      for (int x = 0; x < w_; ++x) out.height_mm.at(x, y) = in_.h[in_.index(x + r_, y + r_)];
    out.distance_evaluations = evaluations_;
    return out;
  }

 private:
  // E of the patch at input pixel (px, py) against exemplar e's patch at (qx, qy); stops once
  // over `bound`.
  float distance(int px, int py, int e, int qx, int qy, float bound) {
    ++evaluations_;
    const Channels& c = ex_[static_cast<std::size_t>(e)];
    float d = 0.0f;
    for (int oy = -r_; oy <= r_; ++oy) {
      const std::size_t a = in_.index(px, py + r_ + oy);
      const std::size_t b = c.index(qx - r_, qy + oy);
      for (int k = 0; k <= 2 * r_; ++k) {
        const float dx = in_.gx[a + k] - c.gx[b + k], dy = in_.gy[a + k] - c.gy[b + k];
        const float dh = in_.h[a + k] - c.h[b + k], ds = in_.s[a + k] - c.s[b + k];
        d += dx * dx + dy * dy + lambda_ * dh * dh + shading_weight_ * ds * ds;
      }
      if (d > bound) return d;
    }
    return d;
  }

  bool valid(int e, int x, int y) const {
    const Channels& c = ex_[static_cast<std::size_t>(e)];
    return x >= r_ && y >= r_ && x < c.width - r_ && y < c.height - r_;
  }

  Match random_match(Random& rng, int px, int py) {
    int k = rng.below(total_centres_);
    const auto it = std::upper_bound(first_centre_.begin(), first_centre_.end(), k) - 1;
    Match m;
    m.e = static_cast<int>(it - first_centre_.begin());
    k -= *it;
    const int cw = ex_[static_cast<std::size_t>(m.e)].width - 2 * r_;
    m.x = r_ + k % cw;
    m.y = r_ + k / cw;
    m.cost = distance(px, py, m.e, m.x, m.y, kInf);
    return m;
  }

  void consider(int px, int py, Match& best, int e, int x, int y) {
    if (!valid(e, x, y) || (e == best.e && x == best.x && y == best.y)) return;
    const float d = distance(px, py, e, x, y, best.cost);
    if (d < best.cost) best = {e, x, y, d};
  }

  void patchmatch_pass(Random& rng, bool forward) {
    const int step = forward ? 1 : -1;
    const std::size_t n = pixels_.size();
    for (std::size_t i = 0; i < n; ++i) {
      const Eigen::Vector2i p = pixels_[forward ? i : n - 1 - i];
      Match& best = nnf_[static_cast<std::size_t>(p.y()) * w_ + p.x()];
      // Propagation: the neighbour already visited this pass, its match shifted along.
      for (const auto& d : {Eigen::Vector2i(step, 0), Eigen::Vector2i(0, step)}) {
        const int nx = p.x() - d.x(), ny = p.y() - d.y();
        if (nx < 0 || ny < 0 || nx >= w_ || ny >= h_ || !domain_.at(nx, ny)) continue;
        const Match& m = nnf_[static_cast<std::size_t>(ny) * w_ + nx];
        if (m.e >= 0) consider(p.x(), p.y(), best, m.e, m.x + d.x(), m.y + d.y());
      }
      // Random search around the current match, halving the radius; and one draw anywhere.
      const Channels& c = ex_[static_cast<std::size_t>(best.e)];
      for (int radius = std::max(c.width, c.height); radius >= 1; radius /= 2) {
        const int x = std::clamp(best.x + rng.below(2 * radius + 1) - radius, r_, c.width - r_ - 1);
        const int y =
            std::clamp(best.y + rng.below(2 * radius + 1) - radius, r_, c.height - r_ - 1);
        consider(p.x(), p.y(), best, best.e, x, y);
      }
      const Match any = random_match(rng, p.x(), p.y());
      if (any.cost < best.cost) best = any;
    }
  }

  void brute_force(int px, int py) {
    Match& best = nnf_[static_cast<std::size_t>(py) * w_ + px];
    if (best.e >= 0) best.cost = distance(px, py, best.e, best.x, best.y, kInf);
    for (int e = 0; e < static_cast<int>(ex_.size()); ++e) {
      const Channels& c = ex_[static_cast<std::size_t>(e)];
      for (int y = r_; y < c.height - r_; ++y)
        for (int x = r_; x < c.width - r_; ++x) {
          const float d = distance(px, py, e, x, y, best.cost);
          if (d < best.cost) best = {e, x, y, d};
        }
    }
  }

  // Every domain pixel's height: the robustly weighted mean of the heights its overlapping
  // matched patches put there.
  void e_step() {
    const std::size_t n = static_cast<std::size_t>(w_) * h_;
    std::vector<float> sum(n, 0.0f), weight(n, 0.0f);
    for (const auto& p : pixels_) {
      const Match& m = nnf_[static_cast<std::size_t>(p.y()) * w_ + p.x()];
      const Channels& c = ex_[static_cast<std::size_t>(m.e)];
      const auto w = static_cast<float>(std::pow(std::max(m.cost, 1e-4f), o_.robust_exponent));
      for (int oy = -r_; oy <= r_; ++oy)
        for (int ox = -r_; ox <= r_; ++ox) {
          const int x = p.x() + ox, y = p.y() + oy;
          if (x < 0 || y < 0 || x >= w_ || y >= h_) continue;
          const std::size_t i = static_cast<std::size_t>(y) * w_ + x;
          sum[i] += w * c.h[c.index(m.x + ox, m.y + oy)];
          weight[i] += w;
        }
    }
    for (int y = 0; y < h_; ++y)
      for (int x = 0; x < w_; ++x) {
        const std::size_t i = static_cast<std::size_t>(y) * w_ + x;
        in_.h[in_.index(x + r_, y + r_)] =
            domain_.at(x, y) && weight[i] > 0.0f ? sum[i] / weight[i] : 0.0f;
      }
  }

  SynthesisOptions o_;
  int r_, w_, h_;
  Channels in_;
  Image<std::uint8_t> domain_;
  std::vector<Eigen::Vector2i> pixels_;
  std::vector<Channels> ex_;
  std::vector<int> first_centre_;
  int total_centres_ = 0;
  std::vector<Match> nnf_;
  float lambda_ = 0.0f;
  float shading_weight_ = static_cast<float>(o_.shading_weight);
  std::int64_t evaluations_ = 0;
};

}  // namespace

std::vector<WrinkleExemplar> rescale_exemplars(std::span<const WrinkleExemplar> exemplars,
                                               double from_mm_per_px, double to_mm_per_px) {
  std::vector<WrinkleExemplar> out;
  const double scale = from_mm_per_px / to_mm_per_px;
  for (const auto& e : exemplars)
    out.push_back({e.name, resample(e.height_mm, scale), resample(e.luminance, scale), e.shaded});
  return out;
}

FloatImage normalised_shading(const FloatImage& luminance, const SynthesisOptions& options) {
  const FloatImage mean = gaussian_blur(luminance, options.normalise_sigma_px);
  FloatImage ratio;
  ratio.resize(luminance.width, luminance.height);
  const auto levels = static_cast<float>(options.feature_levels);
  for (std::size_t i = 0; i < ratio.pixels.size(); ++i)
    ratio.pixels[i] = levels * (luminance.pixels[i] / std::max(mean.pixels[i], 1e-3f) - 1.0f);
  return ratio;
}

ImageGradient wrinkle_features(const FloatImage& luminance, const SynthesisOptions& options) {
  return image_gradient(normalised_shading(luminance, options));
}

Result<WrinkleSynthesis> synthesize_wrinkles(const FloatImage& luminance,
                                             std::span<const PixelRect> regions,
                                             std::span<const WrinkleExemplar> exemplars,
                                             const SynthesisOptions& options,
                                             const Image<std::uint8_t>* excluded) {
  if (options.patch_radius < 1 || options.patch_radius > 8 || options.em_iterations < 1 ||
      options.patchmatch_passes < 1 || !(options.lambda >= 0.0))
    return fail(
        "wrinkle synthesis: patch radius must be 1-8, EM iterations and PatchMatch passes at "
        "least 1, lambda >= 0");
  if (luminance.empty()) return fail("wrinkle synthesis: the input image is empty");
  for (const auto& e : exemplars)
    if (e.height_mm.width != e.luminance.width || e.height_mm.height != e.luminance.height)
      return fail("wrinkle synthesis: exemplar " + e.name +
                  " has height and shading images of different sizes");
  Synthesizer s(
      wrinkle_features(luminance, options), normalised_shading(luminance, options), regions,
      exemplars, options,
      excluded && excluded->width == luminance.width && excluded->height == luminance.height
          ? excluded
          : nullptr);
  if (!s.has_exemplars())
    return fail(
        "wrinkle synthesis: no exemplar is larger than a patch at this pixel size; give "
        "larger exemplars or a finer image");
  return s.run();
}

}  // namespace fb
