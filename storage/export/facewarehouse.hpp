// The FaceWarehouse folder layout, written and read:
//   Tester_N/Blendshape/shape_0.obj .. shape_K.obj   neutral, then the K blendshapes
//   Tester_N/Blendshape/shape.bs                     int32 nShapes(K), nVerts, nFaces, then
//                                                   float32 (K+1) x nVerts x 3, neutral first,
//                                                   all little-endian
//   Tester_N/TrainingPose/pose_0.obj .. pose_19.obj  the fitted expressions
//   Tester_N/TrainingPose/pose_i.png, pose_i.land    colour frame and 2D landmarks, when known
//   Tester_N/TrainingPose/pose_i.mtl, pose_i_texture.png  the expression's texture, when built
// facebooth adds Tester_N/Blendshape/shape_names.txt (one name per blendshape, K lines), which
// FaceWarehouse readers ignore and the importer uses when present.
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "algo/core/image.hpp"
#include "algo/core/result.hpp"
#include "storage/export/export_folder.hpp"
#include "storage/export/mesh_geometry.hpp"
#include "storage/stored_data.hpp"

namespace fb {

std::vector<std::uint8_t> encode_shape_bs(const RigData& rig);
// Positions only (triangles stay empty); checks sizes against the header.
Result<RigData> decode_shape_bs(std::span<const std::uint8_t> bytes, int* face_count = nullptr);

struct FaceWarehouseTester {
  int number = 1;  // the N of Tester_N
  RigData rig;
  std::vector<MeshData> poses;                        // TrainingPose/pose_i.obj
  std::vector<ColorImage> pose_colors;                // optional, same order as poses
  std::vector<std::vector<Landmark>> pose_landmarks;  // optional, same order as poses
  // Optional per-pose texture (PNG in the layout of `uvs`): pose_i.obj then carries the UVs and
  // normals and uses pose_i.mtl, whose map_Kd is pose_i_texture.png.
  std::vector<std::vector<std::uint8_t>> pose_textures;
  const MeshUvs* uvs = nullptr;
};

// Writes Tester_N into an export being assembled.
Result<void> write_facewarehouse_tester(ExportFolder& folder, const FaceWarehouseTester& tester);

// Reads one Tester_N folder: shape.bs (positions), the topology from Blendshape/shape_0.obj,
// and every TrainingPose/pose_i.obj in order. Colour images are not read.
Result<FaceWarehouseTester> import_facewarehouse_tester(const std::filesystem::path& tester_dir);
// Every Tester_N folder under `root`, by N.
Result<std::vector<FaceWarehouseTester>> import_facewarehouse(const std::filesystem::path& root);

}  // namespace fb
