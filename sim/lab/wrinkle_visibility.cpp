// `facebooth-lab diag wrinkle-visibility`: how much of a case's relief the detector can see at
// the booth's resolution, apart from the noise (issue 40 round 7, the scan case's recall). Per
// subject and relief the case is rendered twice with the same sensor noise, with and without the
// relief; both go through the product's ratio image (over the same neutral). Their difference is
// the relief's own signal (to the 8-bit step); the relief-free ratio image is the noise and the
// skin's residue. Per true window: the wrinkle pixels W (|h| >= 0.1 mm), their depth, the
// relief's gradient on W against the noise's, and the detector (zones, every default) run on
// the relief's signal alone at its threshold and at lower ones: the recall a noise-free frame
// would allow, against the recall the real frame gets.
#include <algorithm>
#include <cmath>
#include <iostream>

#include <nlohmann/json.hpp>

#include "algo/wrinkles/wrinkle_detail.hpp"
#include "host/cli/wrinkle_exemplar_files.hpp"
#include "sim/lab/lab_commands.hpp"
#include "sim/lab/wrinkle_case.hpp"
#include "storage/asset_files.hpp"

namespace fb::cli {
namespace {

double robust_sd(std::vector<double> v) {
  if (v.empty()) return 0.0;
  auto mid = v.begin() + static_cast<long>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  const double m = *mid;
  for (auto& x : v) x = std::abs(x - m);
  std::nth_element(v.begin(), mid, v.end());
  return 1.4826 * *mid;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  auto mid = v.begin() + static_cast<long>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

bool in_any(const std::vector<PixelRect>& rs, int x, int y) {
  return std::any_of(rs.begin(), rs.end(), [&](const PixelRect& r) { return r.contains(x, y); });
}

// One subject and relief: per window the figures of the header.
Result<nlohmann::json> visibility(const FaceModel& model, const ExemplarSet& set,
                                  WrinkleRelief relief, std::uint64_t seed, double distance_mm,
                                  double scan_scale) {
  WrinkleCaseOptions co;
  co.relief = relief;
  co.seed = seed;
  co.distance_mm = distance_mm;
  co.scan_crops = set.exemplars;
  for (auto& e : co.scan_crops)  // the scan's relief at another depth scale (round 4, item 3)
    for (auto& v : e.height_mm.pixels) v *= static_cast<float>(scan_scale);
  co.scan_mm_per_px = set.mm_per_px;
  auto c = make_wrinkle_case(model, co);
  if (!c) return c.failure();
  WrinkleCaseOptions bare = co;
  bare.relief = WrinkleRelief::kNone;
  auto none = make_wrinkle_case(model, bare);
  if (!none) return none.failure();
  auto neutral = make_neutral_case(model, co);
  if (!neutral) return neutral.failure();
  const CaseFace with(*c, model, &*neutral), without(*none, model, &*neutral);
  WrinkleDetailOptions wo;
  wo.exemplar_mm_per_px = set.mm_per_px;
  wo.synthesis.em_iterations = 1;  // only the input and the regions are used
  const std::vector<WrinkleExemplar> ex(set.exemplars.begin(), set.exemplars.begin() + 1);
  auto d = wrinkle_detail(c->luminance, c->landmarks, c->face_depth_mm, c->intrinsics.fx, ex, wo,
                          &with.face);
  if (!d) return d.failure();
  auto dn = wrinkle_detail(none->luminance, none->landmarks, none->face_depth_mm,
                           none->intrinsics.fx, ex, wo, &without.face);
  if (!dn) return dn.failure();
  // The relief's signal alone (mid-grey plus the difference of the two ratio images).
  FloatImage clean = d->input;
  for (std::size_t i = 0; i < clean.pixels.size(); ++i)
    clean.pixels[i] = 0.5f + d->input.pixels[i] - dn->input.pixels[i];
  const ImageGradient gs = image_gradient(detection_image(clean, wo.regions));
  const ImageGradient gn = image_gradient(detection_image(dn->input, wo.regions));
  const std::vector<double> thresholds = {wo.regions.gradient_threshold, 0.0025, 0.001};
  std::vector<std::vector<PixelRect>> oracle;
  for (const double t : thresholds) {
    SalientOptions so = wo.regions;
    so.gradient_threshold = static_cast<float>(t);
    oracle.push_back(salient_regions(clean, c->landmarks, so).regions);
  }
  nlohmann::json windows = nlohmann::json::array();
  for (const auto& t : c->true_regions) {
    std::vector<double> depth, relief_g, noise_g;
    int n = 0, found = 0;
    std::vector<int> oracle_found(thresholds.size(), 0);
    for (int y = std::max(1, t.y0); y < std::min(c->luminance.height - 1, t.y1); ++y)
      for (int x = std::max(1, t.x0); x < std::min(c->luminance.width - 1, t.x1); ++x) {
        noise_g.push_back(gn.gy.at(x, y));
        noise_g.push_back(gn.gx.at(x, y));
        const float h = c->true_height_mm.at(x, y);
        if (std::abs(h) < 0.1f) continue;
        ++n;
        depth.push_back(std::abs(h));
        relief_g.push_back(std::max(std::abs(gs.gy.at(x, y)), std::abs(gs.gx.at(x, y))));
        found += d->synthesis.domain.at(x, y) != 0;
        for (std::size_t k = 0; k < thresholds.size(); ++k)
          oracle_found[k] += in_any(oracle[k], x, y);
      }
    const double sd = robust_sd(noise_g);
    int above1 = 0, above2 = 0, above_t = 0;
    for (const double g : relief_g)
      above1 += g > sd, above2 += g > 2 * sd, above_t += g > thresholds[0];
    nlohmann::json j = {{"window", {t.x0, t.y0, t.width(), t.height()}},
                        {"wrinkle_px", n},
                        {"depth_median_mm", median(depth)},
                        {"relief_gradient_median", median(relief_g)},
                        {"noise_gradient_sd", sd},
                        {"relief_gradient_over_threshold", n ? double(above_t) / n : 0.0},
                        {"relief_gradient_over_noise_sd", n ? double(above1) / n : 0.0},
                        {"relief_gradient_over_2_noise_sd", n ? double(above2) / n : 0.0},
                        {"found", n ? double(found) / n : 0.0}};
    for (std::size_t k = 0; k < thresholds.size(); ++k)
      j["noise_free_found"][std::to_string(thresholds[k])] = n ? double(oracle_found[k]) / n : 0.0;
    windows.push_back(j);
  }
  return nlohmann::json{{"relief", relief == WrinkleRelief::kGrooves ? "grooves" : "scan"},
                        {"seed", seed},
                        {"windows", windows}};
}

int run_visibility(const ParsedOptions& options) {
  const auto subjects = options.get_int("subjects");
  const auto first = options.get_int("first-seed");
  if (!subjects || !first || *subjects < 1)
    return report_failure({"--subjects and --first-seed take whole numbers (subjects >= 1)"});
  const auto distance = options.get_double("distance-mm");
  if (!distance || *distance < 500 || *distance > 1500)
    return report_failure({"--distance-mm takes a distance in 500-1500 mm"});
  const auto scan_scale = options.get_double("scan-scale");
  if (!scan_scale || *scan_scale <= 0 || *scan_scale > 10)
    return report_failure({"--scan-scale takes a factor in (0, 10]"});
  auto model = load_face_model();
  if (!model) return report_failure(model.error());
  auto set = load_exemplar_set(default_exemplar_directory());
  if (!set) return report_failure(set.error());
  nlohmann::json runs = nlohmann::json::array();
  for (const auto relief : {WrinkleRelief::kGrooves, WrinkleRelief::kScan})
    for (long long s = 0; s < *subjects; ++s) {
      auto j = visibility(*model, *set, relief, static_cast<std::uint64_t>(*first + s), *distance,
                          *scan_scale);
      if (!j) return report_failure(j.error());
      runs.push_back(*j);
    }
  std::cout << nlohmann::json{{"runs", runs}}.dump(2) << "\n";
  return kExitOk;
}

}  // namespace

std::vector<Command> wrinkle_visibility_commands() {
  return {{{"diag wrinkle-visibility",
            "how much of each case's relief the detector can see without the noise (JSON)",
            "Per subject, relief and true window: wrinkle pixels, their depth, the relief's "
            "gradient against the noise's, and the detector's recall on the relief's signal "
            "alone (thresholds 0.005, 0.0025, 0.001) against the real frame's.",
            {{"subjects", "N", "synthetic subjects", "6"},
             {"first-seed", "N", "seed of the first subject", "1"},
             {"distance-mm", "MM", "the face's distance from the camera", "700"},
             {"scan-scale", "K",
              "the scan case's relief times K (the exemplars' 0.0657 mm a level; the normal map "
              "measures 0.014-0.019: K 0.21-0.29)",
              "1"},
             {"json", "", "JSON on stdout (the only output)", ""}}},
           run_visibility}};
}

}  // namespace fb::cli
