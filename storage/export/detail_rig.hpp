// A blendshape rig whose wrinkle detail is geometry (issue 40 item 5, "applied in the exported
// animation"): for formats that blend morph targets linearly and apply no displacement map per
// frame (glTF), the detail goes into the targets themselves.
//
// The rig's mesh is subdivided at edge midpoints under every texel where the neutral's detail
// or any shape's detail is non-zero (algo/wrinkles/detail_mesh.hpp, the subdivision the OBJ
// export's pose_I_detail.obj uses), and with n the neutral's vertex normals interpolated to the
// new vertices (normalised), per vertex:
//   base    = neutral (subdivided) + h_N n
//   shape_k = shape_k (subdivided) + (h_N + h_k) n
// h_N the neutral's displacement map and h_k shape k's own detail delta (mm, along the normal),
// each the mean of the map at the vertex's corners' UVs. Every term is linear in the maps, so a
// viewer's base + sum_k w_k (shape_k - base) is the rig blended by w plus the detail
// N + sum_k w_k H_k along the neutral's normals: E = N + sum a_i B_i applied to the geometry.
// The displacement is not smoothed at the detail's border (displace_mesh's umbrella pass is not
// linear in the heights); the stored heights are feathered to 0 there already.
#pragma once

#include <vector>

#include "algo/core/image.hpp"
#include "algo/core/result.hpp"
#include "algo/wrinkles/exemplar.hpp"  // FloatImage
#include "storage/export/mesh_geometry.hpp"
#include "storage/stored_data.hpp"

namespace fb {

struct DetailRigInput {
  const RigData* rig = nullptr;  // mm
  const MeshUvs* uvs = nullptr;  // the layout the maps are in; must fit the rig's triangles
  const FloatImage* neutral_mm = nullptr;  // N (row 0 at v = 1, as the store's)
  // Per rig shape, same order: that shape's detail delta H_k, the neutral's size; an empty
  // image (width 0) is a shape without detail.
  const std::vector<FloatImage>* shape_mm = nullptr;
};

struct DetailRig {
  RigData rig;  // on the subdivided mesh, detail in the neutral and in every shape
  MeshUvs uvs;  // the subdivided mesh's layout
  int source_vertices = 0;
  int refined_triangles = 0;  // source triangles subdivided in full
  float max_neutral_height_mm = 0.0f, max_shape_height_mm = 0.0f;  // largest |h_N|, |h_k|
};

// Fails when the layout does not fit, the maps differ in size, or no map has any detail.
Result<DetailRig> make_detail_rig(const DetailRigInput& in);

}  // namespace fb
