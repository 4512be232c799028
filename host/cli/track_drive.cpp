#include "host/cli/track_drive.hpp"

#include <cstdio>
#include <fstream>

#include "host/cli/retarget.hpp"
#include "storage/export/mesh_files.hpp"

namespace fb::cli {

Result<RigDrive> open_rig_drive(const SessionStore& store, const std::string& to,
                                const std::filesystem::path& dir, const std::string& format) {
  if (format != "obj" && format != "ply")
    return fail("--drive-format must be obj or ply (one mesh per frame)");
  if (dir.empty()) return fail("--drive needs --drive-out DIR (one mesh per tracked frame)");
  if (std::filesystem::exists(dir))
    return fail(dir.string() + " already exists: choose another --drive-out");
  auto info = rig_for_target(store, to);
  if (!info) return info.failure();
  auto rig = store.read_rig(info->id);
  if (!rig) return rig.failure();
  RigDrive d;
  d.rig = std::move(*rig);
  d.rig_id = info->id;
  auto columns = take_columns_for_rig(
      std::vector<std::string>(kArkitNames.begin(), kArkitNames.end()), d.rig.shape_names);
  if (!columns) return columns.failure();
  d.columns = std::move(*columns);
  d.dir = dir;
  d.ply = format == "ply";
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) return fail("cannot create " + dir.string() + ": " + ec.message());
  return d;
}

std::vector<float> drive_mesh(const RigDrive& drive, const ArkitFrame& frame) {
  std::vector<float> mesh = drive.rig.neutral;
  for (std::size_t j = 0; j < drive.rig.shapes.size(); ++j) {
    if (drive.columns[j] < 0) continue;
    const float w = frame.weights[static_cast<std::size_t>(drive.columns[j])];
    if (w == 0.0f) continue;
    const auto& s = drive.rig.shapes[j];
    for (std::size_t i = 0; i < mesh.size(); ++i) mesh[i] += w * (s[i] - drive.rig.neutral[i]);
  }
  return mesh;
}

Result<void> drive_frame(RigDrive& drive, const ArkitFrame& frame) {
  const MeshData mesh{drive_mesh(drive, frame), drive.rig.triangles};
  char name[32];
  std::snprintf(name, sizeof name, "frame_%06llu.%s", static_cast<unsigned long long>(frame.index),
                drive.ply ? "ply" : "obj");
  const auto path = drive.dir / name;
  std::ofstream f(path, std::ios::binary);
  if (drive.ply) {
    const auto bytes = encode_ply(mesh);
    f.write(reinterpret_cast<const char*>(bytes.data()),
            static_cast<std::streamsize>(bytes.size()));
  } else {
    f << encode_obj(mesh);
  }
  if (!f) return fail("could not write " + path.string() + "; check the disk");
  ++drive.written;
  return success();
}

}  // namespace fb::cli
