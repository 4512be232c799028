// `facebooth-lab eval wrinkles` and `bench wrinkles`: the wrinkle detail of one expression's
// colour frame (salient regions + texture optimisation, algo/wrinkles/wrinkle_detail.hpp)
// scored against synthetic cases with known relief (sim/lab/wrinkle_case.hpp) and timed against
// the exact brute-force patch search on the same input.
//
// The cases never hand the synthesis the relief they were made from: the grooves case is
// synthetic grooves (not in any exemplar), and the scan case places the scan's forehead and
// crow's-feet crops as truth and synthesises from the brow-furrow exemplars alone.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <iostream>
#include <optional>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "algo/wrinkles/wrinkle_detail.hpp"
#include "host/cli/guide_files.hpp"
#include "host/cli/progress.hpp"
#include "host/cli/wrinkle_exemplar_files.hpp"
#include "sim/lab/lab_commands.hpp"
#include "sim/lab/wrinkle_case.hpp"
#include "sim/lab/wrinkle_tracking_bench.hpp"
#include "storage/asset_files.hpp"

namespace fb::cli {

namespace {

using Clock = std::chrono::steady_clock;

bool is_truth_crop(const std::string& name) {
  return name.rfind("forehead_", 0) == 0 || name.rfind("crows_feet_", 0) == 0;
}

// Height (mm) to grey: 128 + 150 levels per mm.
cv::Mat height_picture(const FloatImage& h, const PixelRect& r) {
  cv::Mat m(r.height(), r.width(), CV_8UC3);
  for (int y = 0; y < r.height(); ++y)
    for (int x = 0; x < r.width(); ++x) {
      const auto v = static_cast<std::uint8_t>(
          std::clamp(128.0f + 150.0f * h.at(r.x0 + x, r.y0 + y), 0.0f, 255.0f));
      m.at<cv::Vec3b>(y, x) = {v, v, v};
    }
  return m;
}

// Colour frame | regions (detected green, true blue) | true height | synthesised height, over
// the upper face, each scaled 2x.
Result<void> write_figure(const std::string& path, const WrinkleCase& c, const WrinkleDetail& d) {
  int x0 = c.luminance.width, y0 = c.luminance.height, x1 = 0, y1 = 0;
  for (const auto& r : c.true_regions)
    x0 = std::min(x0, r.x0), y0 = std::min(y0, r.y0), x1 = std::max(x1, r.x1),
    y1 = std::max(y1, r.y1);
  const PixelRect crop{std::max(0, x0 - 15), std::max(0, y0 - 15),
                       std::min(c.luminance.width, x1 + 15), std::min(c.luminance.height, y1 + 15)};
  cv::Mat frame(crop.height(), crop.width(), CV_8UC3);
  for (int y = 0; y < crop.height(); ++y)
    for (int x = 0; x < crop.width(); ++x) {
      const Rgb8 p = c.color.at(crop.x0 + x, crop.y0 + y);
      frame.at<cv::Vec3b>(y, x) = {p.b, p.g, p.r};
    }
  cv::Mat regions = frame.clone();
  auto draw = [&](const PixelRect& r, cv::Scalar colour) {
    cv::rectangle(regions, cv::Rect(r.x0 - crop.x0, r.y0 - crop.y0, r.width(), r.height()), colour,
                  1);
  };
  for (const auto& r : c.true_regions) draw(r, {255, 80, 0});
  for (const auto& r : d.regions.regions) draw(r, {0, 220, 0});
  // The detector's view: its input (grey), marked pixels (red), kept lines (green).
  cv::Mat detector(crop.height(), crop.width(), CV_8UC3);
  for (int y = 0; y < crop.height(); ++y)
    for (int x = 0; x < crop.width(); ++x) {
      const auto v = static_cast<std::uint8_t>(
          std::clamp(255.0f * d.input.at(crop.x0 + x, crop.y0 + y), 0.f, 255.f));
      detector.at<cv::Vec3b>(y, x) =
          d.regions.marked.at(crop.x0 + x, crop.y0 + y) ? cv::Vec3b{0, 0, 255} : cv::Vec3b{v, v, v};
    }
  for (const auto& l : d.regions.lines)
    for (const auto& p : l.pixels)
      if (crop.contains(p.x(), p.y()))
        detector.at<cv::Vec3b>(p.y() - crop.y0, p.x() - crop.x0) = {0, 220, 0};
  std::vector<cv::Mat> panels = {frame, regions, detector, height_picture(c.true_height_mm, crop),
                                 height_picture(d.synthesis.height_mm, crop)};
  for (auto& p : panels) cv::resize(p, p, {}, 2.0, 2.0, cv::INTER_NEAREST);
  cv::Mat all;
  cv::vconcat(panels, all);
  if (!cv::imwrite(path, all)) return fail("cannot write " + path);
  return success();
}

struct Setup {
  FaceModel model;
  ExemplarSet exemplars;
};

Result<Setup> load_setup(const ParsedOptions& options) {
  auto model = load_face_model();
  if (!model) return model.failure();
  const std::string dir = options.get("exemplars");
  auto set =
      load_exemplar_set(dir.empty() ? default_exemplar_directory() : std::filesystem::path(dir));
  if (!set) return set.failure();
  return Setup{std::move(*model), std::move(*set)};
}

WrinkleCaseOptions case_options(const Setup& setup, WrinkleRelief relief, std::uint64_t seed,
                                bool light_vary, double distance_mm = 700.0) {
  WrinkleCaseOptions co;
  co.relief = relief;
  co.seed = seed;
  co.light_vary = light_vary;
  co.distance_mm = distance_mm;
  co.scan_crops = setup.exemplars.exemplars;
  co.scan_mm_per_px = setup.exemplars.mm_per_px;
  return co;
}

Result<WrinkleCase> make_case(const Setup& setup, WrinkleRelief relief, std::uint64_t seed,
                              bool light_vary, double distance_mm = 700.0) {
  return make_wrinkle_case(setup.model, case_options(setup, relief, seed, light_vary, distance_mm));
}

std::vector<WrinkleExemplar> exemplars_for(const Setup& setup, WrinkleRelief relief) {
  std::vector<WrinkleExemplar> out;
  for (const auto& e : setup.exemplars.exemplars)
    if (relief == WrinkleRelief::kGrooves || !is_truth_crop(e.name)) out.push_back(e);
  return out;
}

nlohmann::json score_json(const WrinkleScore& s) {
  return {{"height_mae_mm", s.height_mae_mm},
          {"zero_field_mae_mm", s.zero_field_mae_mm},
          {"wrinkle_pixel_mae_mm", s.wrinkle_pixel_mae_mm},
          {"height_correlation", s.height_correlation},
          {"region_recall", s.region_recall},
          {"region_precision", s.region_precision},
          {"max_displacement_outside_mm", s.max_displacement_outside_mm}};
}

const char* drop_name(LineDrop d) {
  switch (d) {
    case LineDrop::kKept:
      return "kept";
    case LineDrop::kShort:
      return "short";
    case LineDrop::kFeature:
      return "feature";
    case LineDrop::kNoZone:
      return "no_zone";
    case LineDrop::kOutline:
      return "outline";
    case LineDrop::kEyelid:
      return "eyelid";
  }
  return "?";
}

// `--explain`: where recall and the outside displacement come from. Per true window its wrinkle
// pixels W (|h| >= 0.1 mm) found, on a feature mask inside a region, or in no region; the lines
// kept and dropped (why); the pixels beyond T + margin above 0.05 mm and the regions they lie in.
nlohmann::json explain_json(const WrinkleCase& c, const WrinkleDetail& d, int margin) {
  nlohmann::json out, windows = nlohmann::json::array();
  auto in_rect = [](const PixelRect& r, int x, int y, int grow) {
    return x >= r.x0 - grow && y >= r.y0 - grow && x < r.x1 + grow && y < r.y1 + grow;
  };
  const auto& regions = d.regions.regions;
  for (const auto& t : c.true_regions) {
    int n = 0, hit = 0, masked = 0, none = 0;
    int mx0 = 1 << 20, my0 = 1 << 20, mx1 = -1, my1 = -1;
    for (int y = t.y0; y < t.y1; ++y)
      for (int x = t.x0; x < t.x1; ++x) {
        if (std::abs(c.true_height_mm.at(x, y)) < 0.1f) continue;
        ++n;
        if (d.synthesis.domain.at(x, y)) {
          ++hit;
          continue;
        }
        bool in_region = false;
        for (const auto& r : regions) in_region = in_region || in_rect(r, x, y, 0);
        (in_region ? masked : none) += 1;
        mx0 = std::min(mx0, x), my0 = std::min(my0, y), mx1 = std::max(mx1, x),
        my1 = std::max(my1, y);
      }
    windows.push_back({{"window", {t.x0, t.y0, t.width(), t.height()}},
                       {"wrinkle_px", n},
                       {"found", hit},
                       {"missed_feature_mask", masked},
                       {"missed_no_region", none},
                       {"missed_box", {mx0, my0, mx1, my1}}});
  }
  out["windows"] = windows;
  nlohmann::json lines = nlohmann::json::array();
  // A line's pixels within 1 px of a true wrinkle pixel (|h| >= 0.1 mm): how much of it is relief.
  auto on_relief = [&](const WrinkleLine& l) {
    int n = 0;
    for (const auto& p : l.pixels) {
      bool hit = false;
      for (int dy = -1; dy <= 1 && !hit; ++dy)
        for (int dx = -1; dx <= 1 && !hit; ++dx)
          hit = c.true_height_mm.contains(p.x() + dx, p.y() + dy) &&
                std::abs(c.true_height_mm.at(p.x() + dx, p.y() + dy)) >= 0.1f;
      n += hit;
    }
    return static_cast<double>(n) / static_cast<double>(std::max<std::size_t>(1, l.pixels.size()));
  };
  for (const auto* set : {&d.regions.lines, &d.regions.dropped})
    for (const auto& l : *set) {
      nlohmann::json j = {{"drop", drop_name(l.drop)},
                          {"zone", l.zone},
                          {"box", {l.box.x0, l.box.y0, l.box.width(), l.box.height()}},
                          {"pixels", l.pixels.size()},
                          {"on_relief", on_relief(l)}};
      if (l.evidence.samples > 0)
        j["evidence"] = {{"length_px", l.evidence.length_px},
                         {"thickness_px", l.evidence.thickness_px},
                         {"contrast", l.evidence.contrast},
                         {"noise", l.evidence.noise},
                         {"consistency", l.evidence.consistency},
                         {"score", l.evidence.score},
                         {"continuation", l.evidence.continuation_contrast},
                         {"continuation_score", l.evidence.continuation_score}};
      lines.push_back(j);
    }
  out["lines"] = lines;
  nlohmann::json outside = nlohmann::json::array();
  for (int y = 0; y < d.input.height; ++y)
    for (int x = 0; x < d.input.width; ++x) {
      const float v = d.synthesis.height_mm.at(x, y);
      if (std::abs(v) <= 0.05f) continue;
      bool near_truth = false;
      int dist = 1 << 20;
      for (const auto& t : c.true_regions) {
        near_truth = near_truth || in_rect(t, x, y, margin);
        const int dx = std::max({t.x0 - x, 0, x - (t.x1 - 1)});
        const int dy = std::max({t.y0 - y, 0, y - (t.y1 - 1)});
        dist = std::min(dist, std::max(dx, dy));
      }
      if (near_truth) continue;
      int region = -1;
      for (std::size_t r = 0; r < regions.size() && region < 0; ++r)
        if (in_rect(regions[r], x, y, 0)) region = static_cast<int>(r);
      outside.push_back({{"at", {x, y}}, {"mm", v}, {"region", region}, {"px_from_truth", dist}});
    }
  out["outside_over_0.05"] = outside;
  return out;
}

// The eval's method options beyond the regions (round 5's ratio image, light and gate).
WrinkleDetailOptions detail_options(const ParsedOptions& options, const Setup& setup) {
  WrinkleDetailOptions wo;
  wo.exemplar_mm_per_px = setup.exemplars.mm_per_px;
  wo.ratio_image = !options.flag("no-ratio");
  wo.local_light = options.flag("local-light");
  wo.ratio_cubic = options.flag("cubic");
  wo.regions.forehead_across = options.flag("forehead-across");
  wo.regions.join_forehead_rows = options.flag("join-rows");
  if (const auto f = options.get_int("feather"); f) wo.feather_px = static_cast<int>(*f);
  if (const std::string g = options.get("gate"); !g.empty()) {
    const auto comma = g.find(',');
    wo.gate_low = std::stod(g.substr(0, comma));
    wo.gate_high = std::stod(g.substr(comma + 1));
  }
  if (const std::string t = options.get("threshold"); !t.empty())
    wo.regions.gradient_threshold = std::stof(t);
  if (const auto k = options.get_int("min-line"); k) wo.regions.min_line_px = static_cast<int>(*k);
  if (const auto k = options.get_int("min-crows-feet"); k)
    wo.regions.min_crows_feet_px = static_cast<int>(*k);
  wo.regions.zone_majority = !options.flag("no-zone-majority");
  wo.regions.forehead_rows_only = options.flag("forehead-rows");
  if (const auto k = options.get_int("trace-in-zones"); k)
    wo.regions.trace_in_zones = static_cast<int>(*k);
  if (const auto k = options.get_int("row-gap"); k)
    wo.regions.forehead_row_gap_px = static_cast<int>(*k);
  if (const std::string f = options.get("line-fade"); !f.empty()) {
    const auto comma = f.find(',');
    wo.line_core_px = std::stoi(f.substr(0, comma));
    wo.line_reach_px = std::stoi(f.substr(comma + 1));
  }
  if (const std::string t = options.get("line-test"); !t.empty()) {
    const auto a = t.find(',');
    wo.regions.line_test_min_px = std::stoi(t.substr(0, a));
    if (a != std::string::npos) wo.regions.line_keep_score = std::stod(t.substr(a + 1));
  }
  if (const auto k = options.get_int("silhouette-margin"); k)
    wo.regions.silhouette_margin_px = static_cast<int>(*k);
  if (const auto k = options.get_int("line-extend"); k)
    wo.regions.evidence.extend_px = static_cast<int>(*k);
  if (const auto k = options.get_int("keep-near-lines"); k)
    wo.keep_near_lines_px = static_cast<int>(*k);
  return wo;
}

int run_eval_wrinkles(const ParsedOptions& options) {
  const auto subjects = options.get_int("subjects");
  const auto first = options.get_int("first-seed");
  if (!subjects || !first || *subjects < 1)
    return report_failure({"--subjects and --first-seed take whole numbers (subjects >= 1)"});
  auto setup = load_setup(options);
  if (!setup) return report_failure(setup.error());
  const bool vary = options.get("light") == "vary";
  const bool given = options.get("regions") == "truth";
  const bool zones = options.get("regions") == "zones";
  if (!given && !zones && options.get("regions") != "detected")
    return report_failure({"--regions takes detected, zones or truth"});
  const auto distance = options.get_double("distance-mm");
  if (!distance || *distance < 500 || *distance > 1500)
    return report_failure({"--distance-mm takes a distance in 500-1500 mm"});
  WrinkleDetailOptions wo = detail_options(options, *setup);
  wo.regions.wrinkle_zones = zones;
  const bool meshes = !options.flag("no-meshes");
  nlohmann::json runs = nlohmann::json::array(), summary;
  WrinkleScore worst{0, 0, 0, 1, 1, 1, 0};
  Progress progress("eval wrinkles", 2 * static_cast<int>(*subjects));
  for (const auto relief : {WrinkleRelief::kGrooves, WrinkleRelief::kScan}) {
    const std::string name = relief == WrinkleRelief::kGrooves ? "grooves" : "scan";
    const std::vector<WrinkleExemplar> ex = exemplars_for(*setup, relief);
    WrinkleScore mean;
    for (long long s = 0; s < *subjects; ++s) {
      const auto seed = static_cast<std::uint64_t>(*first + s);
      auto c = make_case(*setup, relief, seed, vary, *distance);
      if (!c) return report_failure(c.error());
      if (given) {
        wo.given_regions.clear();
        for (const auto& r : c->true_regions)
          wo.given_regions.push_back(PixelRect{r.x0 - 5, r.y0 - 5, r.x1 + 5, r.y1 + 5});
      }
      std::optional<WrinkleCase> neutral;
      if (meshes && wo.ratio_image) {
        auto n =
            make_neutral_case(setup->model, case_options(*setup, relief, seed, vary, *distance));
        if (!n) return report_failure(n.error());
        neutral = std::move(*n);
      }
      const CaseFace face(*c, setup->model, neutral ? &*neutral : nullptr);
      const auto t0 = Clock::now();
      auto d = wrinkle_detail(c->luminance, c->landmarks, c->face_depth_mm, c->intrinsics.fx, ex,
                              wo, meshes ? &face.face : nullptr);
      const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();
      if (!d) return report_failure(d.error());
      const WrinkleScore sc = score_wrinkles(*c, *d, wo.regions.margin_px);
      mean.height_mae_mm += sc.height_mae_mm / *subjects;
      mean.zero_field_mae_mm += sc.zero_field_mae_mm / *subjects;
      mean.wrinkle_pixel_mae_mm += sc.wrinkle_pixel_mae_mm / *subjects;
      mean.height_correlation += sc.height_correlation / *subjects;
      mean.region_recall += sc.region_recall / *subjects;
      mean.region_precision += sc.region_precision / *subjects;
      mean.max_displacement_outside_mm =
          std::max(mean.max_displacement_outside_mm, sc.max_displacement_outside_mm);
      worst.height_mae_mm = std::max(worst.height_mae_mm, sc.height_mae_mm);
      worst.zero_field_mae_mm = std::max(worst.zero_field_mae_mm, sc.zero_field_mae_mm);
      worst.wrinkle_pixel_mae_mm = std::max(worst.wrinkle_pixel_mae_mm, sc.wrinkle_pixel_mae_mm);
      worst.height_correlation = std::min(worst.height_correlation, sc.height_correlation);
      worst.region_recall = std::min(worst.region_recall, sc.region_recall);
      worst.region_precision = std::min(worst.region_precision, sc.region_precision);
      worst.max_displacement_outside_mm =
          std::max(worst.max_displacement_outside_mm, sc.max_displacement_outside_mm);
      nlohmann::json run = score_json(sc);
      run["relief"] = name;
      run["seed"] = seed;
      run["regions_detected"] = d->regions.regions.size();
      run["true_regions"] = c->true_regions.size();
      run["max_outside_at"] = {sc.max_outside_x, sc.max_outside_y};
      run["regions"] = nlohmann::json::array();
      for (const auto& r : d->regions.regions)
        run["regions"].push_back({r.x0, r.y0, r.width(), r.height()});
      run["true_windows"] = nlohmann::json::array();
      for (const auto& r : c->true_regions)
        run["true_windows"].push_back({r.x0, r.y0, r.width(), r.height()});
      run["mm_per_px"] = d->image_mm_per_px;
      if (options.flag("explain")) run["explain"] = explain_json(*c, *d, wo.regions.margin_px);
      run["seconds"] = seconds;
      runs.push_back(run);
      const std::string png = options.get("png-prefix");
      if (s == 0 && !png.empty())
        if (auto ok = write_figure(png + "-" + name + ".png", *c, *d); !ok)
          return report_failure(ok.error());
      progress.update(static_cast<int>(runs.size()));
    }
    summary[name] = score_json(mean);
    summary[name]["exemplars"] = ex.size();
  }
  nlohmann::json out = score_json(worst);
  out["worst_of"] = runs.size();
  out["by_relief"] = summary;
  out["light"] = vary ? "vary (per-take light drawn from the seed)" : "the booth's key light";
  out["distance_mm"] = *distance;
  out["regions"] = given   ? "given: the true windows + 5 px (the paper's user rectangles)"
                   : zones ? "detected in the wrinkle zones (forehead, glabella, crow's feet)"
                           : "detected (salient regions)";
  out["ratio_image"] = meshes && wo.ratio_image;
  out["local_light"] = meshes && wo.local_light;
  out["budget"] = {{"height_mae_mm", "<= 0.15"},
                   {"region_recall", ">= 0.9"},
                   {"region_precision", ">= 0.8"},
                   {"max_displacement_outside_mm", "<= 0.05"}};
  out["scoring"] =
      "top level: the worst case over every run (by_relief: means, max for the displacement). "
      "T = the true relief windows' pixel boxes; height_mae_mm over T (zero_field_mae_mm: the "
      "same for an all-zero height field; height_correlation: Pearson, synthesised vs true, over "
      "T); "
      "wrinkle pixels W = T with |true height| >= 0.1 mm "
      "(wrinkle_pixel_mae_mm over W); region_recall = W inside detected regions / W; "
      "region_precision = detected pixels inside T grown by the 5 px margin / detected pixels; "
      "max_displacement_outside_mm = max |synthesised height| outside T + margin. grooves: "
      "synthetic grooves 0.2-1.0 mm deep, all 24 exemplars; scan: the scan's forehead_0 and "
      "crows_feet_*_0 relief as truth, synthesised from the brow_furrows_* exemplars only";
  out["runs"] = runs;
  std::cout << out.dump(2) << "\n";
  return kExitOk;
}

int run_bench_wrinkles(const ParsedOptions& options) {
  auto setup = load_setup(options);
  if (!setup) return report_failure(setup.error());
  const auto seed = options.get_int("seed");
  if (!seed) return report_failure(seed.error());
  auto c = make_case(*setup, WrinkleRelief::kGrooves, static_cast<std::uint64_t>(*seed), false);
  if (!c) return report_failure(c.error());
  auto neutral = make_neutral_case(
      setup->model,
      case_options(*setup, WrinkleRelief::kGrooves, static_cast<std::uint64_t>(*seed), false));
  if (!neutral) return report_failure(neutral.error());
  const CaseFace face(*c, setup->model, &*neutral);
  WrinkleDetailOptions wo;
  wo.exemplar_mm_per_px = setup->exemplars.mm_per_px;
  nlohmann::json methods = nlohmann::json::object();
  double seconds[2] = {0, 0};
  std::optional<WrinkleDetail> kept;
  for (const auto search : {PatchSearch::kPatchMatch, PatchSearch::kBruteForce}) {
    wo.synthesis.search = search;
    const auto t0 = Clock::now();
    auto d = wrinkle_detail(c->luminance, c->landmarks, c->face_depth_mm, c->intrinsics.fx,
                            setup->exemplars.exemplars, wo, &face.face);
    const double s = std::chrono::duration<double>(Clock::now() - t0).count();
    if (!d) return report_failure(d.error());
    const WrinkleScore sc = score_wrinkles(*c, *d, wo.regions.margin_px);
    const bool pm = search == PatchSearch::kPatchMatch;
    seconds[pm ? 0 : 1] = s;
    methods[pm ? "patchmatch" : "brute_force"] = {
        {"per_expression_s", s},
        {"final_energy", d->synthesis.energy.back()},
        {"patch_distances", d->synthesis.distance_evaluations},
        {"height_mae_mm", sc.height_mae_mm}};
    if (pm) methods["patchmatch"]["patches"] = d->synthesis.patches;
    if (pm) kept = std::move(*d);
  }
  auto guide = load_guide(setup->model, "");
  if (!guide) return report_failure(guide.error());
  auto map_size = options.get_int("map-size");
  if (!map_size) return report_failure(map_size.error());
  auto tracking =
      bench_detail_blend(setup->model, *guide, *c, *kept, static_cast<int>(*map_size), 1000);
  if (!tracking) return report_failure(tracking.error());
  nlohmann::json out = {
      {"per_expression_s", seconds[0]},
      {"peer", "brute_force (exact nearest patch over all 24 exemplars, same input and regions)"},
      {"peer_per_expression_s", seconds[1]},
      {"speedup_vs_peer", seconds[0] > 0 ? seconds[1] / seconds[0] : 0.0},
      {"image", std::to_string(c->luminance.width) + "x" + std::to_string(c->luminance.height) +
                    " frontal, raised brows, grooves case seed " + std::to_string(*seed)},
      {"threads", 1},
      {"budget", {{"per_expression_s", "<= 1.0 (one core)"}}},
      {"timed",
       "ratio image (the neutral warped through the meshes) + salient regions + exemplars "
       "re-shaded per region and resampled + EM synthesis (4 iterations)"},
      {"methods", methods},
      {"tracking_overhead_ms", (*tracking)["tracking_overhead_ms"]},
      {"tracking", *tracking}};
  std::cout << out.dump(2) << "\n";
  return kExitOk;
}

}  // namespace

std::vector<Command> wrinkles_eval_commands() {
  const OptionSpec exemplars{"exemplars", "DIR",
                             "exemplar set (facebooth-convert-exemplars); default: the data "
                             "directory's wrinkle_exemplars",
                             ""};
  const OptionSpec json{"json", "", "JSON report on stdout (the only output format)", ""};
  return {
      {{"eval wrinkles",
        "wrinkle heights from a colour frame against synthetic relief of known depth (JSON)",
        "Per subject two cases, a textured synthetic face with raised brows rendered as the "
        "booth's colour frame: synthetic grooves 0.2-1.0 mm deep (all exemplars), and the "
        "scan's own forehead and crow's-feet relief (synthesised from the brow-furrow "
        "exemplars only). --png-prefix P writes P-grooves.png and P-scan.png: frame, "
        "regions (true blue, detected green), true and synthesised heights.",
        {{"subjects", "N", "synthetic subjects per case", "3"},
         {"first-seed", "N", "seed of the first subject", "1"},
         {"light", "booth|vary", "the booth's key light or a per-take one", "booth"},
         {"distance-mm", "MM", "the face's distance from the camera", "700"},
         {"regions", "detected|zones|truth",
          "detected regions; detected only in the wrinkle zones (SalientOptions::"
          "wrinkle_zones); or the true windows + 5 px given as the paper's user "
          "rectangles (scores the synthesis alone)",
          "zones"},
         {"png-prefix", "P", "figures", ""},
         {"no-ratio", "", "no expression ratio image (the frame as it is)", ""},
         {"local-light", "", "the exemplars re-shaded per region for its mesh normal", ""},
         {"no-meshes", "", "neither (the frame and its landmarks alone: before round 5)", ""},
         {"cubic", "", "warp the neutral with Catmull-Rom (not bilinear)", ""},
         {"forehead-across", "", "the forehead region across its zone (round 4)", ""},
         {"join-rows", "", "forehead lines at one height join however far apart", ""},
         {"gate", "LOW,HIGH", "heights fall to 0 where the relief is no more than noise", ""},
         {"threshold", "T", "the detector's gradient threshold (SalientOptions)", ""},
         {"min-crows-feet", "PX", "the shortest line kept at the eyes", "8"},
         {"feather", "PX", "heights faded to 0 over PX at the domain's edge", "5"},
         {"min-line", "PX", "the shortest line kept (SalientOptions)", "10"},
         {"forehead-rows", "", "in the forehead zone only sign changes along y", ""},
         {"no-zone-majority", "", "a line in the zone of its centroid (round 5)", ""},
         {"trace-in-zones", "0|1|2", "lines cut at the zones' borders (1: crow's feet only)", "1"},
         {"row-gap", "PX", "forehead clusters at one height join across this gap", "0"},
         {"line-fade", "CORE,REACH",
          "heights fade from CORE to 0 at REACH px from a line (0,0: off)", "1,4"},
         {"explain", "", "per run: windows' missed pixels, lines kept/dropped, outside pixels", ""},
         {"line-test", "MIN[,SCORE]",
          "the line test: a line from MIN px shorter than the shortest kept when its "
          "continuation scores SCORE (0: off)",
          "5,5"},
         {"silhouette-margin", "PX",
          "no marks this close to the fitted mesh's silhouette (-1: off)", "5"},
         {"line-extend", "PX", "the line test's continuation beyond each end", "8"},
         {"keep-near-lines", "PX", "heights only this close to a kept line (0: all)", "0"},
         exemplars,
         json}},
       run_eval_wrinkles},
      {{"bench wrinkles",
        "time one expression's wrinkle detail, PatchMatch against brute force (JSON)",
        "One 640x480 frontal frame (grooves case), one thread, both searches on the same "
        "input and regions. Then section 4's tracked-frame detail: the maps blended per "
        "frame over 1000 frames of random weights (tracking_overhead_ms) against the same "
        "blend over every texel of the full maps.",
        {{"seed", "N", "subject", "1"},
         {"map-size", "PX",
          "detail map height for the tracking blend (facebooth wrinkles' default)", "256"},
         exemplars,
         json}},
       run_bench_wrinkles}};
}

}  // namespace fb::cli
