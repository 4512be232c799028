// The FaceWarehouse importer (storage/export/facewarehouse, mesh_files): shape.bs, OBJ, and a
// whole Tester_N folder built from both. The first byte picks the part:
//   0: shape.bs bytes   1: OBJ text
//   2: a u32 (little-endian) length n, n bytes of shape.bs, then the OBJ text used for
//      Blendshape/shape_0.obj and TrainingPose/pose_0.obj
#include <cstring>

#include "storage/export/facewarehouse.hpp"
#include "storage/export/mesh_files.hpp"
#include "tests/fuzz/fuzz_util.hpp"

namespace {

void check_rig(const fb::RigData& rig) {
  // What decodes must encode into bytes that decode to the same counts.
  const auto bytes = fb::encode_shape_bs(rig);
  auto again = fb::decode_shape_bs(bytes);
  fb::fuzz::require(again.ok() && again->vertex_count() == rig.vertex_count() &&
                        again->shape_count() == rig.shape_count(),
                    "encode_shape_bs of a decoded rig decodes to the same counts");
}

void check_mesh(const fb::MeshData& mesh) {
  for (auto t : mesh.triangles)
    fb::fuzz::require(static_cast<int>(t) < mesh.vertex_count(), "triangle index in range");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const std::uint8_t* body = data + 1;
  const std::size_t body_size = size - 1;
  switch (data[0] % 3) {
    case 0: {
      auto rig = fb::decode_shape_bs(std::span<const std::uint8_t>(body, body_size));
      if (rig) check_rig(*rig);
      break;
    }
    case 1: {
      auto obj = fb::parse_obj(fb::fuzz::text(body, body_size), "fuzz.obj");
      if (obj) check_mesh(obj->mesh);
      break;
    }
    default: {
      std::uint32_t n = 0;
      if (body_size < 4) break;
      std::memcpy(&n, body, 4);
      if (n > body_size - 4) break;
      const auto tester = fb::fuzz::scratch_dir() / "Tester_1";
      std::filesystem::create_directories(tester / "Blendshape");
      std::filesystem::create_directories(tester / "TrainingPose");
      fb::fuzz::write_file(tester / "Blendshape" / "shape.bs", fb::fuzz::text(body + 4, n));
      const auto obj = fb::fuzz::text(body + 4 + n, body_size - 4 - n);
      fb::fuzz::write_file(tester / "Blendshape" / "shape_0.obj", obj);
      fb::fuzz::write_file(tester / "TrainingPose" / "pose_0.obj", obj);
      auto t = fb::import_facewarehouse_tester(tester);
      if (t) {
        check_mesh(t->rig.neutral_mesh());
        for (const auto& pose : t->poses) check_mesh(pose);
      }
      break;
    }
  }
  return 0;
}
