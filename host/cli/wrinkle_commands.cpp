// `facebooth wrinkles`: the subject's own wrinkles (issue 40) from a stored session's colour
// frames, stored as detail maps with the session's rig; exports then carry them.
#include <cstdio>
#include <iostream>

#include <nlohmann/json.hpp>

#include "host/cli/commands.hpp"
#include "host/cli/progress.hpp"
#include "host/cli/session_wrinkles.hpp"
#include "host/cli/wrinkle_exemplar_files.hpp"
#include "storage/asset_files.hpp"

namespace fb::cli {

namespace {

// The exemplars: the default set (or --exemplars DIR), plus or (--user-exemplars-only) instead
// of the --exemplar pairs. Returns what was loaded, for the report.
Result<nlohmann::json> exemplars_of(const ParsedOptions& options, WrinkleSessionOptions& wo) {
  const std::string exemplar_dir = options.get("exemplars");
  auto set = load_exemplar_set(exemplar_dir.empty() ? default_exemplar_directory()
                                                    : std::filesystem::path(exemplar_dir));
  if (!set) return set.failure();
  const auto user = options.all("exemplar");
  const bool only = options.flag("user-exemplars-only");
  if (only && user.empty())
    return fail("--user-exemplars-only needs at least one --exemplar HEIGHT.png:COLOUR.png");
  auto px = options.get_double("exemplar-mm-per-px");
  if (!px) return px.failure();
  wo.exemplar_mm_per_px = set->mm_per_px;
  if (!only) wo.exemplars = std::move(set->exemplars);
  nlohmann::json report = {{"default_set", only ? 0 : static_cast<int>(wo.exemplars.size())},
                           {"user", nlohmann::json::array()}};
  for (const auto& arg : user) {
    auto spec = parse_user_exemplar(arg);
    if (!spec) return spec.failure();
    auto loaded = load_user_exemplar(*spec, *px, set->mm_per_px);
    if (!loaded) return loaded.failure();
    report["user"].push_back({{"height", spec->height.string()},
                              {"colour", spec->colour.string()},
                              {"copies", loaded->size()},
                              {"size_px", loaded->front().height_mm.width}});
    for (auto& e : *loaded) wo.exemplars.push_back(std::move(e));
  }
  return report;
}

// "[CAPTURE:]x,y,w,h" in the colour frame's pixels.
Result<WrinkleSessionOptions::GivenRegion> parse_region(const std::string& arg) {
  const std::string form =
      "--region takes x,y,w,h in the colour frame's pixels, or CAPTURE:x,y,w,h "
      "for one capture (e.g. 250,90,140,40), not '" +
      arg + "'";
  WrinkleSessionOptions::GivenRegion g;
  std::string rest = arg;
  if (const auto colon = arg.find(':'); colon != std::string::npos) {
    try {
      std::size_t used = 0;
      g.capture = std::stoi(arg.substr(0, colon), &used);
      if (used != colon || *g.capture < 0) return fail(form);
    } catch (const std::exception&) {
      return fail(form);
    }
    rest = arg.substr(colon + 1);
  }
  int v[4];
  char tail = 0;
  if (std::sscanf(rest.c_str(), "%d,%d,%d,%d%c", &v[0], &v[1], &v[2], &v[3], &tail) != 4)
    return fail(form);
  if (v[2] <= 0 || v[3] <= 0 || v[0] < 0 || v[1] < 0)
    return fail(form + ": x, y >= 0 and w, h > 0");
  g.rect = PixelRect::from_size(v[0], v[1], v[2], v[3]);
  return g;
}

int run_wrinkles(const ParsedOptions& options) {
  const std::string store_dir = options.get("store");
  auto sid = options.get_int("session");
  if (store_dir.empty() || !sid || *sid <= 0)
    return report_failure(
        {"give --store DIR and --session ID (a session with a rig and fitted expressions)"});
  auto size = options.get_int("size");
  if (!size) return report_failure(size.error());
  if (*size < 64 || *size > 4096)
    return report_failure({"--size must be 64..4096 texels (the map's height)"});
  auto model = load_face_model();
  if (!model) return report_failure(model.error());
  WrinkleSessionOptions wo;
  wo.size = static_cast<int>(*size);
  wo.save = !options.flag("no-save");
  auto exemplars = exemplars_of(options, wo);
  if (!exemplars) return report_failure(exemplars.error());
  for (const auto& arg : options.all("region")) {
    auto region = parse_region(arg);
    if (!region) return report_failure(region.error());
    wo.regions.push_back(*region);
  }
  wo.also_detect = options.flag("also-detect");
  if (options.flag("zones") && options.flag("no-zones"))
    return report_failure({"--zones (the default) and --no-zones exclude each other"});
  wo.zones = !options.flag("no-zones");
  wo.local_light = options.flag("local-light");
  if (wo.also_detect && wo.regions.empty())
    return report_failure({"--also-detect goes with --region (detection is the default)"});
  StoreOptions so;
  so.read_only = !wo.save;
  so.create = false;
  auto store = SessionStore::open(store_dir, so);
  if (!store) return report_failure(store.error());
  std::optional<Progress> progress;
  auto reports = wrinkle_session(*store, *sid, *model, wo, [&](int done, int total) {
    if (!progress) progress.emplace("wrinkles", total);
    progress->update(done);
  });
  if (!reports) return report_failure(reports.error());
  nlohmann::json out = {{"session", *sid}, {"size", *size}, {"saved", wo.save}};
  out["exemplars"] = *exemplars;
  out["details"] = nlohmann::json::array();
  for (const auto& r : *reports) {
    nlohmann::json j = {{"capture", r.capture_index},
                        {"expression", r.expression},
                        {"regions", r.regions},
                        {"given_regions", r.given_regions},
                        {"texels_with_detail", r.texels_with_detail},
                        {"max_height_mm", r.max_height_mm},
                        {"ratio_to_neutral", r.ratio_to_neutral},
                        {"seconds", r.seconds}};
    if (r.stored) j["detail_id"] = *r.stored;
    out["details"].push_back(j);
  }
  std::cout << out.dump(2) << "\n";
  return kExitOk;
}

}  // namespace

std::vector<Command> wrinkle_commands() {
  return {{{"wrinkles",
            "the subject's wrinkles from a session's colour frames, as detail maps on the rig",
            "For each capture with a fitted mesh (the neutral first): the mesh is placed by its "
            "3D landmarks, the frontal colour frame is pulled into the depth camera's grid "
            "through the unit calibration the session recorded, wrinkle regions are found and "
            "a height field is synthesised from exemplars of real skin (EM texture "
            "optimisation, PatchMatch); the heights become a displacement map (mm) and a "
            "tangent-space normal map in the face model's UV layout, stored with the session "
            "and the rig serving it. Exports use them: glTF normalTexture, OBJ norm and a "
            "subdivided, displaced mesh per expression, and the per-expression maps for the "
            "blendshapes. See docs/wrinkles.md for what the "
            "synthesis does and does not reach. JSON report on stdout, progress on stderr.",
            {{"store", "DIR", "session store", ""},
             {"session", "ID", "the session (needs a rig and its fitted captures)", ""},
             {"size", "PX",
              "map height; its width is one square per tile of the UV layout (256: finer than "
              "the colour frame's 1.2 mm pixels on the face)",
              "256"},
             {"exemplars", "DIR",
              "an exemplar set in data/wrinkle_exemplars' format (exemplars.json + PNGs)", ""},
             {"exemplar", "HEIGHT:COLOUR[:MM_PER_LEVEL]",
              "a user exemplar (repeatable): a grey height map (8- or 16-bit) and a colour image "
              "of the same skin, pixel for pixel; heights are grey levels about mid-grey times "
              "MM_PER_LEVEL (default 1/16384 for 16-bit, 1/128 for 8-bit); added to the set with "
              "its rotated copies (30-150 degrees)",
              ""},
             {"exemplar-mm-per-px", "MM", "the user exemplars' pixel size on the skin", "0.25"},
             {"user-exemplars-only", "", "synthesise from the --exemplar pairs alone", ""},
             {"region", "[CAPTURE:]X,Y,W,H",
              "a wrinkle region by hand (repeatable), in the colour frame's pixels, for every "
              "capture or only CAPTURE; replaces the detected regions (see --also-detect)",
              ""},
             {"also-detect", "", "with --region: keep the detected regions too", ""},
             {"zones", "",
              "the default: detect wrinkles only where expression wrinkles form (forehead, "
              "glabella, crow's feet; from the landmarks): fewer false regions, lines "
              "elsewhere (cheeks, under the eyes) not synthesised (docs/wrinkles.md)",
              ""},
             {"no-zones", "", "the paper's detector alone: lines anywhere on the face", ""},
             {"local-light", "",
              "shade the exemplars per region for the fitted mesh's normal there (measured "
              "worse on the lab's cases; docs/wrinkles.md)",
              ""},
             {"no-save", "", "build and report only; the store is opened read-only", ""}}},
           run_wrinkles}};
}

}  // namespace fb::cli
