// `facebooth-lab diag wrinkles` and `diag wrinkle-scale`: the measurements behind issue 40's
// height budget (docs/wrinkles.md, "Why the heights are no better than zero"). Not scores: they
// take the synthesis apart on the grooves case with the true windows as regions.
//
// diag wrinkles, per subject: the true relief's statistics in the windows T; how the booth's
// frame shows the relief (the frame minus the same subject rendered without relief, against
// shade_relief of the true heights, which is how the exemplars are shaded: correlation); the
// spread of the skin's own texture and noise against the relief's in the normalised shading the
// synthesis matches; then the synthesis (true windows + 5 px) under the chosen variant, with its
// MAE, correlation and the offset at which it best correlates with the truth. Variants: the
// exemplars' heights scaled (--scales, each re-shaded), re-shaded for a skin patch turned
// towards (nx, ny, 1) instead of facing the camera (--local-light), synthetic grooves as
// exemplars (--oracle: the case's kind of relief), the albedo cancelled by dividing by the same
// subject's frame without relief (--ratio, plus 2 levels of noise).
//
// diag wrinkle-scale: the scan's displacement grey levels in mm, measured on its own
// tangent-space normal map (slopes regressed on the displacement's gradient), per crop and
// high-pass, against the 0.0657 mm per level the shipped exemplars assume.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "algo/core/mix64.hpp"
#include "algo/render/rasterizer.hpp"
#include "algo/wrinkles/wrinkle_detail.hpp"
#include "host/cli/wrinkle_exemplar_files.hpp"
#include "sim/lab/lab_commands.hpp"
#include "sim/lab/wrinkle_case.hpp"
#include "storage/asset_files.hpp"

namespace fb::cli {
namespace {

struct Pairs {
  double n = 0, sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0;
  void add(double a, double b) { ++n, sa += a, sb += b, saa += a * a, sbb += b * b, sab += a * b; }
  double corr() const {
    const double c = sab - sa * sb / n, va = saa - sa * sa / n, vb = sbb - sb * sb / n;
    return c / std::sqrt(std::max(1e-30, va * vb));
  }
  double slope() const { return (sab - sa * sb / n) / std::max(1e-30, saa - sa * sa / n); }
};

bool in_any(const std::vector<PixelRect>& rs, int x, int y) {
  return std::any_of(rs.begin(), rs.end(), [&](const PixelRect& r) { return r.contains(x, y); });
}

template <typename F>
void for_t(const WrinkleCase& c, int border, F f) {
  for (int y = border; y < c.luminance.height - border; ++y)
    for (int x = border; x < c.luminance.width - border; ++x)
      if (in_any(c.true_regions, x, y)) f(x, y);
}

double noise(std::uint64_t i) {
  const double u = ((mix64(2 * i + 77) >> 11) + 0.5) * 0x1.0p-53;
  const double v = (mix64(2 * i + 78) >> 11) * 0x1.0p-53;
  return std::sqrt(-2.0 * std::log(u)) * std::cos(2.0 * M_PI * v);
}

// The booth's key light for a skin patch whose normal is (nx, ny, 1) in the model frame (x
// right, y up; the face frontal, so the camera's frame is (x, -y, -z)).
SkinLight local_light(double nx, double ny) {
  return skin_light_for(Eigen::Vector3f(static_cast<float>(nx), static_cast<float>(-ny), -1.0f),
                        WrinkleDetailOptions{}.to_light);
}

// Six orientations of grooves 0.2-1.0 mm deep, sigma 0.9 mm, 7.3 mm apart, at 0.25 mm per px.
std::vector<WrinkleExemplar> oracle_exemplars(const SkinLight& light) {
  std::vector<WrinkleExemplar> out;
  for (int a = 0; a < 6; ++a) {
    WrinkleExemplar x;
    x.name = "oracle_" + std::to_string(30 * a);
    x.height_mm.resize(400, 400);
    const double ang = a * M_PI / 6, ca = std::cos(ang), sa = std::sin(ang);
    for (int y = 0; y < 400; ++y)
      for (int i = 0; i < 400; ++i) {
        const double u = (i - 200) * 0.25, v = (y - 200) * 0.25, across = -u * sa + v * ca;
        double h = 0.0;
        for (int g = -6; g <= 6; ++g) {
          const double depth = 0.2 + 0.2 * ((g + 6) % 5);
          const double d = across - g * 7.3 - std::sin(u * ca / 9.0 + g);
          h -= depth * std::exp(-0.5 * d * d / 0.81);
        }
        x.height_mm.at(i, y) = static_cast<float>(h);
      }
    x.luminance = shade_relief(x.height_mm, 0.25, light);
    out.push_back(std::move(x));
  }
  return out;
}

// How the frame shows the relief, and what else is in it.
void relief_in_frame(const WrinkleCase& c, const WrinkleCase& flat, double mm_per_px) {
  const SynthesisOptions so;
  const FloatImage pred = normalised_shading(shade_relief(c.true_height_mm, mm_per_px), so);
  const FloatImage s1 = normalised_shading(c.luminance, so),
                   s0 = normalised_shading(flat.luminance, so);
  Pairs p;
  double tex = 0, rel = 0;
  for_t(c, 0, [&](int x, int y) {
    p.add(pred.at(x, y), s1.at(x, y) - s0.at(x, y));
    tex += s0.at(x, y) * s0.at(x, y);
    rel += std::pow(s1.at(x, y) - s0.at(x, y), 2);
  });
  std::printf(
      "  relief in the frame vs shade_relief(truth): corr %.3f; rms normalised shading in T: "
      "texture+noise %.2f, relief %.2f levels\n",
      p.corr(), std::sqrt(tex / p.n), std::sqrt(rel / p.n));
}

void score_synthesis(const WrinkleCase& c, const FloatImage& h) {
  Pairs p;
  double mae = 0, zero = 0, mag = 0;
  for_t(c, 0, [&](int x, int y) {
    const float t = c.true_height_mm.at(x, y), g = h.at(x, y);
    p.add(g, t);
    mae += std::abs(g - t), zero += std::abs(t), mag += std::abs(g);
  });
  double best = -2;
  int bx = 0, by = 0;
  for (int oy = -2; oy <= 2; ++oy)
    for (int ox = -2; ox <= 2; ++ox) {
      Pairs q;
      for_t(c, 2, [&](int x, int y) { q.add(h.at(x + ox, y + oy), c.true_height_mm.at(x, y)); });
      if (q.corr() > best) best = q.corr(), bx = ox, by = oy;
    }
  std::printf(
      "  synthesis: MAE %.3f (zero field %.3f), corr %.3f, mean |h| %.3f; best corr %.3f at "
      "(%+d, %+d) px\n",
      mae / p.n, zero / p.n, p.corr(), mag / p.n, best, bx, by);
}

// The neutral frame (brows down, no relief) warped into the expression's image through the two
// meshes (algo/wrinkles' warp_neutral, as the product does).
Result<FloatImage> warp_case_neutral(const FaceModel& model, const WrinkleCase& c,
                                     const WrinkleCase& neutral) {
  const CaseFace face(c, model, &neutral);
  RasterBuffers raster;
  raster.reset(c.intrinsics.width, c.intrinsics.height);
  if (auto ok = rasterize(c.intrinsics, face.expression, model.triangles, {}, raster); !ok)
    return ok.failure();
  return warp_neutral(c.intrinsics, raster, face.face.neutral, neutral.luminance);
}

std::vector<double> parse_list(const std::string& s) {
  std::vector<double> out;
  std::stringstream in(s);
  for (std::string item; std::getline(in, item, ',');) out.push_back(std::stod(item));
  return out;
}

int run_diag(const ParsedOptions& options) {
  auto model = load_face_model();
  if (!model) return report_failure(model.error());
  auto set = load_exemplar_set(default_exemplar_directory());
  if (!set) return report_failure(set.error());
  const bool local = options.flag("local-light"), oracle = options.flag("oracle");
  const SkinLight light =
      local ? local_light(std::stod(options.get("nx")), std::stod(options.get("ny"))) : SkinLight{};
  std::vector<WrinkleExemplar> ex;
  if (oracle) ex = oracle_exemplars(light);
  for (const auto& e : oracle ? std::vector<WrinkleExemplar>{} : set->exemplars)
    for (const double k : parse_list(options.get("scales"))) {
      WrinkleExemplar x = e;
      for (auto& v : x.height_mm.pixels) v *= static_cast<float>(k);
      x.luminance = shade_relief(x.height_mm, set->mm_per_px, light);
      ex.push_back(std::move(x));
    }
  for (int seed = 1; seed <= 3; ++seed) {
    WrinkleCaseOptions co;
    co.seed = static_cast<std::uint64_t>(seed);
    auto c = make_wrinkle_case(*model, co);
    co.relief = WrinkleRelief::kNone;
    auto flat = make_wrinkle_case(*model, co);
    if (!c || !flat) return report_failure(!c ? c.error() : flat.error());
    const double mm_per_px = c->face_depth_mm / c->intrinsics.fx;
    double n = 0, deep = 0;
    for_t(*c, 0, [&](int x, int y) { ++n, deep += std::abs(c->true_height_mm.at(x, y)) >= 0.1; });
    std::printf("seed %d: %.3f mm per px, T %.0f px, %.2f of them >= 0.1 mm deep\n", seed,
                mm_per_px, n, deep / n);
    relief_in_frame(*c, *flat, mm_per_px);
    FloatImage input = c->luminance;
    if (options.flag("ratio"))
      for (std::size_t i = 0; i < input.pixels.size(); ++i)
        input.pixels[i] = static_cast<float>(0.55 * c->luminance.pixels[i] /
                                                 std::max(0.02f, flat->luminance.pixels[i]) +
                                             2.0 / 255.0 * noise(i));
    if (options.flag("neutral-ratio")) {
      auto neutral = make_neutral_case(*model, co);
      if (!neutral) return report_failure(neutral.error());
      auto warped = warp_case_neutral(*model, *c, *neutral);
      if (!warped) return report_failure(warped.error());
      for (std::size_t i = 0; i < input.pixels.size(); ++i)
        if (warped->pixels[i] > 0.02f)
          input.pixels[i] = 0.55f * c->luminance.pixels[i] / warped->pixels[i];
    }
    WrinkleDetailOptions wo;
    wo.exemplar_mm_per_px = oracle ? 0.25 : set->mm_per_px;
    for (const auto& r : c->true_regions)
      wo.given_regions.push_back(PixelRect{r.x0 - 5, r.y0 - 5, r.x1 + 5, r.y1 + 5});
    auto d = wrinkle_detail(input, c->landmarks, c->face_depth_mm, c->intrinsics.fx, ex, wo);
    if (!d) return report_failure(d.error());
    score_synthesis(*c, d->synthesis.height_mm);
  }
  return kExitOk;
}

// The displacement map averaged onto the normal map's grid, and the normal map's slopes along
// image x and y (y down).
struct ScanMaps {
  FloatImage disp, sx, sy;
};

ScanMaps read_scan_maps(const cv::Mat& disp, const cv::Mat& normal) {
  const int n = normal.cols, f = disp.cols / n;
  ScanMaps m;
  m.disp.resize(n, n), m.sx.resize(n, n), m.sy.resize(n, n);
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      float s = 0;
      for (int j = 0; j < f; ++j)
        for (int i = 0; i < f; ++i) s += disp.at<std::uint8_t>(f * y + j, f * x + i);
      m.disp.at(x, y) = s / static_cast<float>(f * f);
      const cv::Vec3b c = normal.at<cv::Vec3b>(y, x);  // BGR: z, y (up), x
      const float nz = std::max(c[0] / 127.5f - 1.0f, 0.2f);
      m.sx.at(x, y) = -(c[2] / 127.5f - 1.0f) / nz;
      m.sy.at(x, y) = (c[1] / 127.5f - 1.0f) / nz;
    }
  return m;
}

int run_scale(const ParsedOptions& options) {
  const std::string dir = options.get("source") + "/";
  const cv::Mat disp =
      cv::imread(dir + "Infinite-Level_02_Disp_NoSmoothUV-4096.jpg", cv::IMREAD_GRAYSCALE);
  const cv::Mat normal = cv::imread(dir + "Infinite-Level_02_Tangent_SmoothUV.jpg");
  if (disp.empty() || normal.empty() || disp.cols % normal.cols != 0)
    return report_failure({"cannot read the scan's maps in " + dir});
  const ScanMaps m = read_scan_maps(disp, normal);
  const double mm_per_px = 63.0 / 580.0 * disp.cols / normal.cols;  // as the converter
  struct Crop {
    const char* name;
    int x, y, w, h;  // in the 4096 map (host/convert_exemplars)
  };
  const Crop crops[] = {{"forehead", 1650, 640, 800, 320},
                        {"brow_furrows", 1950, 900, 240, 240},
                        {"crows_feet_right", 1400, 1100, 240, 240},
                        {"crows_feet_left", 2440, 1100, 240, 240}};
  const int f = disp.cols / normal.cols;
  for (const double hp_mm : {1.5, 3.0, 6.0}) {
    const double sigma = hp_mm / mm_per_px;
    const ImageGradient g = image_gradient(high_pass(m.disp, sigma));
    const FloatImage hx = high_pass(m.sx, sigma), hy = high_pass(m.sy, sigma);
    Pairs all;
    for (const auto& r : crops) {
      Pairs px, py;
      for (int y = r.y / f; y < (r.y + r.h) / f; ++y)
        for (int x = r.x / f; x < (r.x + r.w) / f; ++x) {
          px.add(g.gx.at(x, y) / mm_per_px, hx.at(x, y));
          py.add(g.gy.at(x, y) / mm_per_px, hy.at(x, y));
          all.add(g.gx.at(x, y) / mm_per_px, hx.at(x, y));
          all.add(g.gy.at(x, y) / mm_per_px, hy.at(x, y));
        }
      std::printf(
          "high-pass %.1f mm, %-16s x: corr %.2f, %.4f mm/level; y: corr %.2f, %.4f mm/level\n",
          hp_mm, r.name, px.corr(), px.slope(), py.corr(), py.slope());
    }
    std::printf("high-pass %.1f mm, all crops, x and y: corr %.2f, %.4f mm/level\n", hp_mm,
                all.corr(), all.slope());
  }
  return kExitOk;
}

}  // namespace

std::vector<Command> wrinkle_diag_commands() {
  std::vector<Command> out = wrinkle_visibility_commands();
  for (auto& c : std::vector<Command>{
           {{"diag wrinkles",
             "take the wrinkle synthesis apart on the grooves case (subjects 1-3, true windows)",
             "Prints per subject how the frame shows the relief, the skin texture's share, and the "
             "synthesis under a variant (docs/wrinkles.md).",
             {{"scales", "K[,K...]", "the exemplars' heights times each K (re-shaded)", "1"},
              {"local-light", "", "shade the exemplars for a skin patch with normal (nx, ny, 1)",
               ""},
              {"nx", "X", "with --local-light", "0"},
              {"ny", "Y", "with --local-light (the forehead: 0.3)", "0.3"},
              {"oracle", "", "synthetic grooves as the exemplars", ""},
              {"ratio", "", "the frame divided by the subject's frame without relief", ""},
              {"neutral-ratio", "",
               "the frame divided by the subject's neutral frame (brows down, no relief) warped "
               "through the meshes",
               ""}}},
            run_diag},
           {{"diag wrinkle-scale",
             "the scan's displacement grey levels in mm, from its own normal map",
             "Regresses the normal map's slopes on the displacement's gradient in the exemplar "
             "crops, per high-pass.",
             {{"source", "DIR", "../shared/skin/lps", "/work/shared/skin/lps"}}},
            run_scale}})
    out.push_back(std::move(c));
  return out;
}

}  // namespace fb::cli
