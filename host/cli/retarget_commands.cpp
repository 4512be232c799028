// `facebooth retarget`: a stored take's expression weights driving another subject's rig, each
// frame written as a mesh in the export formats (host/cli/retarget.hpp).
#include <filesystem>
#include <iostream>

#include <nlohmann/json.hpp>

#include "algo/core/clock.hpp"
#include "host/cli/commands.hpp"
#include "host/cli/export_summary.hpp"
#include "host/cli/retarget.hpp"
#include "storage/asset_files.hpp"
#include "storage/export/export_session.hpp"

namespace fb::cli {

namespace {

namespace fs = std::filesystem;

int run_retarget(const ParsedOptions& options) {
  const std::string store_dir = options.get("store");
  if (store_dir.empty()) return report_failure({"--store DIR is required"});
  auto take_id = options.get_int("take");
  if (!take_id || *take_id <= 0) return report_failure({"--take ID is required (an ID > 0)"});
  if (options.get("to").empty())
    return report_failure({"--to is required: session:ID or subject:ID, whose rig to drive"});
  if (options.get("out").empty()) return report_failure({"--out DIR is required"});
  auto format = parse_export_format(options.get("format"));
  if (!format) return report_failure(format.error());
  if (*format == ExportFormat::kGlb)
    return report_failure(
        {"--format glb carries the rig but no animation (the exporter has "
         "none): use obj, ply or facewarehouse for the frames, and `facebooth "
         "export --take ID` for the weights as Live Link Face CSV"});
  auto every = options.get_int("every");
  if (!every || *every < 1) return report_failure({"--every N needs N >= 1"});
  ExportRequest request;
  request.format = *format;
  request.out = options.get("out");
  request.overwrite = options.flag("force");
  if (fs::exists(request.out) && !request.overwrite)
    return report_failure({request.out.string() +
                           " already exists: choose another --out, or pass --force to replace it"});
  StoreOptions so;
  so.read_only = true;
  so.create = false;
  auto store = SessionStore::open(store_dir, so);
  if (!store) return report_failure(store.error());
  auto take = store->read_take(*take_id);
  if (!take) return report_failure(take.error());
  auto target = rig_for_target(*store, options.get("to"));
  if (!target) return report_failure(target.error());
  auto rig = store->read_rig(target->id);
  if (!rig) return report_failure(rig.error());
  auto columns = take_columns_for_rig(take->info.shape_names, rig->shape_names);
  if (!columns) return report_failure(columns.error());
  const auto t0 = Clock::now();
  ExportContent content;
  content.name = "retarget";
  for (int f = 0; f < take->info.frame_count; f += static_cast<int>(*every)) {
    content.poses.push_back({retarget_frame(*take, f, *rig, *columns), rig->triangles});
    content.pose_names.push_back("frame_" + std::to_string(f));
  }
  const double evaluate_ms = ms_since(t0);
  content.rig = std::move(*rig);
  content.source = {{"kind", "retarget"},
                    {"take", std::to_string(*take_id)},
                    {"take_subject", std::to_string(take->info.subject)},
                    {"rig", std::to_string(target->id)},
                    {"rig_subject", std::to_string(target->subject)},
                    {"poses", "one per take frame (every " + std::to_string(*every) +
                                  "th), the take's weights on the rig, model frame (no head "
                                  "pose)"}};
  if (auto model = load_face_model()) use_face_model_uvs(content, *model);
  auto summary = export_content(content, request);
  if (!summary) return report_failure(summary.error());
  int driven = 0;
  for (int c : *columns) driven += c >= 0 ? 1 : 0;
  nlohmann::json out = summary_json(*summary);
  out["format"] = to_string(*format);
  out["frames"] = content.poses.size();
  out["take_frames"] = take->info.frame_count;
  out["rig"] = target->id;
  out["rig_subject"] = target->subject;
  out["take_subject"] = take->info.subject;
  out["shapes_driven"] = driven;
  out["shapes"] = content.rig.shape_count();
  out["evaluate_ms"] = evaluate_ms;
  std::cout << out.dump(2) << std::endl;
  return kExitOk;
}

}  // namespace

std::vector<Command> retarget_commands() {
  return {{{"retarget",
            "drive another subject's rig with a stored take's expression weights",
            "Reads take ID from --store (its per-frame weights: the tracker's 52 ARKit curves) "
            "and the rig of --to, matches the rig's shapes to the take's curves by name (the "
            "face model's names to ARKit's: eyeBlink_L <- eyeBlinkLeft, both browInnerUp halves "
            "<- browInnerUp), and writes every frame's mesh (neutral + sum of weight x shape "
            "delta, in the rig's model frame, without the take's head pose) as the export's "
            "poses: obj and ply poses/pose_I.EXT (I = the frame's position in the output, the "
            "manifest lists the frames), facewarehouse TrainingPose/pose_I.obj, beside the rig "
            "itself. JSON summary on stdout.",
            {{"store", "DIR", "session store holding the take and the rig", ""},
             {"take", "ID", "the take (`facebooth store info` lists them)", ""},
             {"to", "TARGET",
              "whose rig: session:ID (the rig serving that session) or subject:ID (their "
              "newest)",
              ""},
             {"out", "DIR", "output folder (must not exist unless --force)", ""},
             {"format", "F", "obj, ply or facewarehouse", "obj"},
             {"every", "N", "write every Nth frame", "1"},
             {"force", "", "replace --out if it exists", ""}}},
           run_retarget}};
}

}  // namespace fb::cli
