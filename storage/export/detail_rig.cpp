#include "storage/export/detail_rig.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "algo/texture/texel_map.hpp"
#include "algo/wrinkles/detail_mesh.hpp"

namespace fb {

namespace {

// Where the subdivision goes: |N| + sum_k |H_k| per texel (non-zero wherever any map has detail).
FloatImage detail_support(const FloatImage& neutral, const std::vector<FloatImage>& shapes) {
  FloatImage support = neutral;
  for (float& h : support.pixels) h = std::abs(h);
  for (const auto& s : shapes)  // an empty image (no detail) adds nothing
    for (std::size_t i = 0; i < s.pixels.size(); ++i) support.pixels[i] += std::abs(s.pixels[i]);
  return support;
}

Result<void> check(const DetailRigInput& in) {
  if (in.rig == nullptr || in.uvs == nullptr || in.neutral_mm == nullptr || in.shape_mm == nullptr)
    return fail("detail rig: missing input");
  if (!in.uvs->fits(in.rig->triangles))
    return fail("detail rig: the UV layout does not fit the rig's mesh");
  if (in.shape_mm->size() != in.rig->shapes.size())
    return fail("detail rig: " + std::to_string(in.shape_mm->size()) + " shape maps for " +
                std::to_string(in.rig->shapes.size()) + " shapes");
  const FloatImage& n = *in.neutral_mm;
  if (n.width <= 0 || n.pixels.size() != static_cast<std::size_t>(n.width) * n.height)
    return fail("detail rig: the neutral has no displacement map");
  for (const auto& s : *in.shape_mm)
    if (s.width != 0 && (s.width != n.width || s.height != n.height))
      return fail("detail rig: a shape's detail map is " + std::to_string(s.width) + " x " +
                  std::to_string(s.height) + ", the neutral's " + std::to_string(n.width) + " x " +
                  std::to_string(n.height));
  return success();
}

float largest(const std::vector<float>& values) {
  float m = 0.0f;
  for (float v : values) m = std::max(m, std::abs(v));
  return m;
}

}  // namespace

Result<DetailRig> make_detail_rig(const DetailRigInput& in) {
  if (auto ok = check(in); !ok) return ok.failure();
  const RigData& rig = *in.rig;
  const FloatImage support = detail_support(*in.neutral_mm, *in.shape_mm);
  if (largest(support.pixels) <= 0.0f)
    return fail("detail rig: neither the neutral nor any shape has wrinkle detail");

  DetailMeshInput mesh_in;
  mesh_in.vertices = rig.neutral;
  mesh_in.triangles = rig.triangles;
  mesh_in.uvs = in.uvs->uvs;
  mesh_in.triangle_uvs = in.uvs->triangle_uvs;
  mesh_in.displacement_mm = &support;
  auto mesh = subdivided_detail_mesh(mesh_in);
  if (!mesh) return mesh.failure();
  auto texels = make_texel_map(mesh->uvs, mesh->triangle_uvs, support.width, support.height);
  if (!texels) return texels.failure();
  const std::size_t n = mesh->undisplaced.size() / 3;
  auto heights = [&](const FloatImage& map) {
    return corner_mean_heights(map, texels->triangle, n, mesh->triangles, mesh->uvs,
                               mesh->triangle_uvs);
  };

  // The neutral's smooth normals carried to the new vertices (a flat triangle's midpoints would
  // otherwise all take its face normal).
  std::vector<float> normals =
      interpolate_midpoints(vertex_normals(rig.neutral, rig.triangles), 3, mesh->parents);
  for (std::size_t v = 0; v < n; ++v) {
    const float length = std::hypot(normals[3 * v], normals[3 * v + 1], normals[3 * v + 2]);
    for (int k = 0; k < 3; ++k) normals[3 * v + k] /= length > 1e-12f ? length : 1.0f;
  }
  DetailRig out;
  out.source_vertices = rig.vertex_count();
  out.refined_triangles = mesh->refined_triangles;
  const std::vector<float> h_neutral = heights(*in.neutral_mm);
  out.max_neutral_height_mm = largest(h_neutral);
  out.rig.neutral = mesh->undisplaced;
  for (std::size_t i = 0; i < out.rig.neutral.size(); ++i)
    out.rig.neutral[i] += h_neutral[i / 3] * normals[i];
  for (std::size_t k = 0; k < rig.shapes.size(); ++k) {
    std::vector<float> shape = interpolate_midpoints(rig.shapes[k], 3, mesh->parents);
    const FloatImage& map = (*in.shape_mm)[k];
    const std::vector<float> h = map.width > 0 ? heights(map) : std::vector<float>(n, 0.0f);
    out.max_shape_height_mm = std::max(out.max_shape_height_mm, largest(h));
    for (std::size_t i = 0; i < shape.size(); ++i)
      shape[i] += (h_neutral[i / 3] + h[i / 3]) * normals[i];
    out.rig.shapes.push_back(std::move(shape));
  }
  out.rig.shape_names = rig.shape_names;
  out.rig.triangles = std::move(mesh->triangles);
  out.uvs.uvs = std::move(mesh->uvs);
  out.uvs.triangle_uvs = std::move(mesh->triangle_uvs);
  return out;
}

}  // namespace fb
