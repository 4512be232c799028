// `facebooth wrinkles`: the subject's own wrinkles (issue 40) from a stored session's colour
// frames, stored as detail maps with the session's rig; exports then carry them.
#include <iostream>

#include <nlohmann/json.hpp>

#include "host/cli/commands.hpp"
#include "host/cli/progress.hpp"
#include "host/cli/session_wrinkles.hpp"
#include "host/cli/wrinkle_exemplar_files.hpp"
#include "storage/asset_files.hpp"

namespace fb::cli {

namespace {

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
  const std::string exemplar_dir = options.get("exemplars");
  auto set = load_exemplar_set(exemplar_dir.empty() ? default_exemplar_directory()
                                                    : std::filesystem::path(exemplar_dir));
  if (!set) return report_failure(set.error());
  WrinkleSessionOptions wo;
  wo.size = static_cast<int>(*size);
  wo.save = !options.flag("no-save");
  wo.exemplars = std::move(set->exemplars);
  wo.exemplar_mm_per_px = set->mm_per_px;
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
  out["details"] = nlohmann::json::array();
  for (const auto& r : *reports) {
    nlohmann::json j = {{"capture", r.capture_index},
                        {"expression", r.expression},
                        {"regions", r.regions},
                        {"texels_with_detail", r.texels_with_detail},
                        {"max_height_mm", r.max_height_mm},
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
            "and the rig serving it. Exports use them: glTF normalTexture, OBJ norm, and the "
            "per-expression maps for the blendshapes. See docs/wrinkles.md for what the "
            "synthesis does and does not reach. JSON report on stdout, progress on stderr.",
            {{"store", "DIR", "session store", ""},
             {"session", "ID", "the session (needs a rig and its fitted captures)", ""},
             {"size", "PX",
              "map height; its width is one square per tile of the UV layout (256: finer than "
              "the colour frame's 1.2 mm pixels on the face)",
              "256"},
             {"exemplars", "DIR",
              "an exemplar set in data/wrinkle_exemplars' format (exemplars.json + PNGs)", ""},
             {"no-save", "", "build and report only; the store is opened read-only", ""}}},
           run_wrinkles}};
}

}  // namespace fb::cli
