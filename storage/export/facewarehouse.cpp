#include "storage/export/facewarehouse.hpp"

#include <algorithm>
#include <cstring>
#include <sstream>

#include "storage/durable_file.hpp"
#include "storage/export/mesh_files.hpp"
#include "storage/export/png_file.hpp"

namespace fb {

namespace fs = std::filesystem;

std::vector<std::uint8_t> encode_shape_bs(const RigData& rig) {
  const std::int32_t header[3] = {rig.shape_count(), rig.vertex_count(),
                                  static_cast<std::int32_t>(rig.triangles.size() / 3)};
  const std::size_t block = rig.neutral.size() * sizeof(float);
  std::vector<std::uint8_t> out(sizeof header + block * (rig.shapes.size() + 1));
  std::memcpy(out.data(), header, sizeof header);  // little-endian hosts (see session_store.cpp)
  std::uint8_t* p = out.data() + sizeof header;
  std::memcpy(p, rig.neutral.data(), block);
  for (const auto& s : rig.shapes) {
    p += block;
    std::memcpy(p, s.data(), block);
  }
  return out;
}

Result<RigData> decode_shape_bs(std::span<const std::uint8_t> bytes, int* face_count) {
  std::int32_t header[3] = {};
  if (bytes.size() < sizeof header) return fail("shape.bs is shorter than its 12-byte header");
  std::memcpy(header, bytes.data(), sizeof header);
  const auto [shapes, verts, faces] = std::tuple(header[0], header[1], header[2]);
  if (shapes < 0 || verts <= 0 || faces < 0 || shapes > 100000 || verts > 50000000) {
    return fail("shape.bs has an implausible header (" + std::to_string(shapes) + " shapes, " +
                std::to_string(verts) + " vertices): not a FaceWarehouse blendshape file");
  }
  const std::size_t block = static_cast<std::size_t>(verts) * 3;
  const std::size_t want = sizeof header + (static_cast<std::size_t>(shapes) + 1) * block * 4;
  if (bytes.size() != want) {
    return fail("shape.bs holds " + std::to_string(bytes.size()) + " bytes but its header (" +
                std::to_string(shapes) + " shapes x " + std::to_string(verts) +
                " vertices) needs " + std::to_string(want) + ": the file is truncated or damaged");
  }
  RigData rig;
  const std::uint8_t* p = bytes.data() + sizeof header;
  rig.neutral.resize(block);
  std::memcpy(rig.neutral.data(), p, block * 4);
  rig.shapes.resize(static_cast<std::size_t>(shapes));
  for (auto& s : rig.shapes) {
    p += block * 4;
    s.resize(block);
    std::memcpy(s.data(), p, block * 4);
  }
  for (int j = 0; j < shapes; ++j) rig.shape_names.push_back("shape_" + std::to_string(j + 1));
  if (face_count != nullptr) *face_count = faces;
  return rig;
}

Result<void> write_facewarehouse_tester(ExportFolder& folder, const FaceWarehouseTester& t) {
  const std::string base = "Tester_" + std::to_string(t.number) + "/";
  const std::string comment = "facebooth FaceWarehouse-layout export, millimetres";
  if (auto r = folder.write_file(base + "Blendshape/shape.bs", encode_shape_bs(t.rig)); !r)
    return r;
  if (auto r = folder.write_text(base + "Blendshape/shape_0.obj",
                                 encode_obj(t.rig.neutral_mesh(), comment + ", neutral"));
      !r) {
    return r;
  }
  std::string names;
  for (int j = 0; j < t.rig.shape_count(); ++j) {
    const std::string& name = t.rig.shape_names[static_cast<std::size_t>(j)];
    names += name + "\n";
    if (auto r = folder.write_text(base + "Blendshape/shape_" + std::to_string(j + 1) + ".obj",
                                   encode_obj(t.rig.shape_mesh(j), comment + ", " + name));
        !r) {
      return r;
    }
  }
  if (auto r = folder.write_text(base + "Blendshape/shape_names.txt", names); !r) return r;
  for (std::size_t i = 0; i < t.poses.size(); ++i) {
    const std::string stem = base + "TrainingPose/pose_" + std::to_string(i);
    const bool textured = i < t.pose_textures.size() && !t.pose_textures[i].empty() &&
                          t.uvs != nullptr && t.uvs->fits(t.poses[i].triangles);
    ObjExtras extras;
    if (textured) {
      const std::string leaf = "pose_" + std::to_string(i);
      extras = {t.uvs, true, leaf + ".mtl", "skin"};
      if (auto r = folder.write_text(stem + ".mtl", "newmtl skin\nKa 0 0 0\nKd 1 1 1\nKs 0.05 0.05 "
                                                    "0.05\nNs 20\nd 1\nillum 2\nmap_Kd " +
                                                        leaf + "_texture.png\n");
          !r)
        return r;
      if (auto r = folder.write_file(stem + "_texture.png", t.pose_textures[i]); !r) return r;
    }
    if (auto r = folder.write_text(stem + ".obj",
                                   encode_obj(t.poses[i], comment, textured ? &extras : nullptr));
        !r)
      return r;
    if (i < t.pose_colors.size() && !t.pose_colors[i].empty()) {
      auto png = encode_png(t.pose_colors[i]);
      if (!png) return png.failure();
      if (auto r = folder.write_file(stem + ".png", *png); !r) return r;
    }
    if (i < t.pose_landmarks.size() && !t.pose_landmarks[i].empty()) {
      std::ostringstream land;
      land << t.pose_landmarks[i].size() << "\n";
      for (const auto& p : t.pose_landmarks[i]) land << p.u << " " << p.v << "\n";
      if (auto r = folder.write_text(stem + ".land", land.str()); !r) return r;
    }
  }
  return success();
}

Result<FaceWarehouseTester> import_facewarehouse_tester(const fs::path& dir) {
  FaceWarehouseTester t;
  const std::string name = dir.filename().string();
  if (name.rfind("Tester_", 0) == 0) t.number = std::atoi(name.c_str() + 7);
  const fs::path bs = dir / "Blendshape" / "shape.bs";
  auto bytes = read_file_bytes(bs);
  if (!bytes) {
    return fail(dir.string() +
                " is not a FaceWarehouse tester folder (no readable "
                "Blendshape/shape.bs)");
  }
  int faces = 0;
  auto rig = decode_shape_bs(*bytes, &faces);
  if (!rig) return fail(bs.string() + ": " + rig.error().message);
  auto topology = read_obj(dir / "Blendshape" / "shape_0.obj");
  if (!topology) {
    return fail("the topology comes from Blendshape/shape_0.obj, which cannot be read: " +
                topology.error().message);
  }
  if (topology->mesh.vertex_count() != rig->vertex_count()) {
    return fail("Blendshape/shape_0.obj has " + std::to_string(topology->mesh.vertex_count()) +
                " vertices but shape.bs has " + std::to_string(rig->vertex_count()) +
                ": the folder mixes different meshes");
  }
  if (topology->face_count != faces) {
    return fail("Blendshape/shape_0.obj has " + std::to_string(topology->face_count) +
                " faces but shape.bs says " + std::to_string(faces));
  }
  rig->triangles = std::move(topology->mesh.triangles);
  if (auto names = read_file_bytes(dir / "Blendshape" / "shape_names.txt"); names) {
    std::vector<std::string> list;
    std::istringstream in(std::string(names->begin(), names->end()));
    for (std::string line; std::getline(in, line);) {
      if (!line.empty()) list.push_back(line);
    }
    if (list.size() == rig->shapes.size()) rig->shape_names = std::move(list);
  }
  t.rig = std::move(*rig);
  for (int i = 0;; ++i) {
    const fs::path pose = dir / "TrainingPose" / ("pose_" + std::to_string(i) + ".obj");
    std::error_code ec;
    if (!fs::exists(pose, ec)) break;
    auto mesh = read_obj(pose);
    if (!mesh) return mesh.failure();
    t.poses.push_back(std::move(mesh->mesh));
  }
  return t;
}

Result<std::vector<FaceWarehouseTester>> import_facewarehouse(const fs::path& root) {
  std::error_code ec;
  if (!fs::is_directory(root, ec)) return fail(root.string() + " is not a folder");
  std::vector<fs::path> dirs;
  for (const auto& e : fs::directory_iterator(root, ec)) {
    if (e.is_directory() && e.path().filename().string().rfind("Tester_", 0) == 0) {
      dirs.push_back(e.path());
    }
  }
  if (dirs.empty()) return fail(root.string() + " has no Tester_N folders");
  std::vector<FaceWarehouseTester> testers;
  for (const auto& d : dirs) {
    auto t = import_facewarehouse_tester(d);
    if (!t) return t.failure();
    testers.push_back(std::move(*t));
  }
  std::sort(testers.begin(), testers.end(),
            [](const auto& a, const auto& b) { return a.number < b.number; });
  return testers;
}

}  // namespace fb
