// `facebooth texture`: the subject's texture atlas from a stored session's colour frames.
#include <fstream>
#include <iostream>

#include <nlohmann/json.hpp>

#include "host/cli/commands.hpp"
#include "host/cli/progress.hpp"
#include "host/cli/session_texture.hpp"
#include "storage/asset_files.hpp"

namespace fb::cli {

namespace {

int run_texture(const ParsedOptions& options) {
  const std::string store_dir = options.get("store");
  auto sid = options.get_int("session");
  if (store_dir.empty() || !sid || *sid <= 0)
    return report_failure({"give --store DIR and --session ID (a session with a fitted neutral)"});
  auto size = options.get_int("size");
  if (!size) return report_failure(size.error());
  auto model = load_face_model();
  if (!model) return report_failure(model.error());
  const bool save = !options.flag("no-save");
  StoreOptions so;
  so.read_only = !save;
  so.create = false;
  auto store = SessionStore::open(store_dir, so);
  if (!store) return report_failure(store.error());
  auto info = store->session(*sid);
  if (!info) return report_failure(info.error());
  std::string note;
  if (auto c = session_calibration(*info, note); !c) return report_failure(c.error());
  if (!note.empty()) std::cerr << "facebooth: note: " << note << "\n";
  std::optional<Progress> progress;
  auto reports = texture_session(*store, *sid, *model, static_cast<int>(*size),
                                 options.flag("expressions"), save, [&](int done, int total) {
                                   if (!progress) progress.emplace("texture", total);
                                   progress->update(done);
                                 });
  if (!reports) return report_failure(reports.error());
  nlohmann::json out = {{"session", *sid}, {"size", *size}, {"saved", save}};
  out["calibration"] = note.empty() ? "recorded" : "defaults";
  for (const auto& r : *reports) {
    nlohmann::json j = {{"capture", r.capture_index}, {"expression", r.expression},
                        {"frames", r.frames},         {"frames_aligned", r.frames_aligned},
                        {"views", r.views},           {"observed_fraction", r.observed_fraction},
                        {"seconds", r.seconds}};
    if (r.stored) j["texture_id"] = *r.stored;
    out["textures"].push_back(j);
  }
  const std::string png = options.get("png");
  if (!png.empty()) {
    if (!save || reports->empty() || !reports->front().stored)
      return report_failure({"--png needs the texture saved (drop --no-save)"});
    auto bytes = store->read_texture(*reports->front().stored);
    if (!bytes) return report_failure(bytes.error());
    std::ofstream f(png, std::ios::binary);
    f.write(reinterpret_cast<const char*>(bytes->data()),
            static_cast<std::streamsize>(bytes->size()));
    if (!f)
      return report_failure(
          {"could not write " + png + "; check the folder exists and is writable"});
    out["png"] = png;
  }
  std::cout << out.dump(2) << "\n";
  return kExitOk;
}

}  // namespace

std::vector<Command> texture_commands() {
  return {{{"texture",
            "the subject's colour texture (face model UV layout) from a session's colour frames",
            "The fitted neutral is placed on its take's frames (3D landmarks, then ICP on every "
            "frame's depth), up to 15 frames spread over the head turn are projected through the "
            "unit calibration the session recorded, their lighting is divided out and they are "
            "blended by view angle; what no frame saw is filled smoothly. Stored with the session "
            "(exports use the newest: glTF baseColorTexture, OBJ map_Kd). --expressions adds one "
            "texture per fitted expression (FaceWarehouse TrainingPose). JSON report on stdout.",
            {{"store", "DIR", "session store", ""},
             {"session", "ID", "the session (needs its fitted neutral and its frames)", ""},
             {"size", "PX",
              "atlas height; its width is one square per tile of the face model's UV layout "
              "(2: face, back of the head)",
              "1024"},
             {"expressions", "", "also one texture per fitted expression capture", ""},
             {"no-save", "", "build and report only; the store is opened read-only", ""},
             {"png", "FILE", "also write the subject texture to FILE", ""}}},
           run_texture}};
}

}  // namespace fb::cli
