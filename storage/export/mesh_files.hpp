// Wavefront OBJ and PLY for meshes in millimetres: writers for exports, an OBJ reader for
// importing FaceWarehouse-layout folders.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "algo/core/result.hpp"
#include "storage/export/mesh_geometry.hpp"
#include "storage/stored_data.hpp"

namespace fb {

// What an OBJ can carry beyond positions: vertex normals (vn, one per vertex), the UV layout (vt,
// one per UV; OBJ indexes them per corner, so seams need no split) and a material library.
struct ObjExtras {
  const MeshUvs* uvs = nullptr;  // used when it fits the mesh's triangles
  bool normals = false;          // area-weighted vertex normals
  std::string mtllib;            // "mtllib NAME" when not empty
  std::string material;          // "usemtl NAME" when not empty
};

// "v x y z" lines (shortest round-trip float text) and 1-based "f a b c" triangles (with
// extras: "f v/vt/vn" or "f v//vn").
std::string encode_obj(const MeshData& mesh, std::string_view comment = {},
                       const ObjExtras* extras = nullptr);
// Binary little-endian PLY: float x y z vertices, uchar-count uint32 triangle faces.
std::vector<std::uint8_t> encode_ply(const MeshData& mesh, std::string_view comment = {});

struct ObjReadResult {
  MeshData mesh;       // polygons fan-triangulated
  int face_count = 0;  // polygons as written in the file (FaceWarehouse counts quads)
};
// Reads v and f records (f accepts v, v/vt, v//vn, v/vt/vn and negative indices); other records
// are ignored. Errors give the line number.
Result<ObjReadResult> parse_obj(std::string_view text, const std::string& name_for_errors);
Result<ObjReadResult> read_obj(const std::filesystem::path& path);

}  // namespace fb
