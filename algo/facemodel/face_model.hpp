// The face model (ICT FaceKit "Light", MIT) as the project uses it: the skin surface
// (face + back of head), identity PCA modes with sigma built in, expression shapes as
// deltas, landmark and jawline vertex lists. Units are millimetres, model frame
// +X = subject's left, +Y up, +Z out of the face.
//
// The asset format is documented in data/README.md; `parse_face_model` validates the
// header, sizes and checksum and never reads past the buffer.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "algo/core/result.hpp"

namespace fb {

struct FaceModel {
  int vertex_count = 0;       // skin vertices kept (11248: face 0-9408 + back of head 9409-11247)
  int face_vertex_count = 0;  // vertices 0..face_vertex_count-1 are the face region (9409)
  int identity_count = 0;     // 100
  int expression_count = 0;   // 57: the 53 fitting expressions first, then the 4 extras

  std::vector<float> neutral;           // 3 * vertex_count, xyz interleaved, mm
  std::vector<float> identity_basis;    // identity_count blocks of 3 * vertex_count (1 sigma each)
  std::vector<float> expression_basis;  // expression_count blocks of 3 * vertex_count (full shape)
  std::vector<std::string> expression_names;  // e.g. "jawOpen", "mouthSmile_L"
  int fitting_expression_count = 0;           // 53: the ARKit-style set used for fitting

  std::vector<std::uint32_t> triangles;  // 3 * triangle_count, quads split into two triangles
  std::array<std::uint32_t, 68> landmark_vertices{};  // iBUG 68-point order
  std::vector<std::uint32_t> rigid_landmarks;         // positions in the 68-list that stay rigid
  std::vector<std::uint32_t> right_jawline;           // candidates for landmarks 0-7
  std::vector<std::uint32_t> left_jawline;            // candidates for landmarks 9-16
  std::vector<std::uint32_t> right_extended_jawline;
  std::vector<std::uint32_t> left_extended_jawline;
  std::vector<std::uint32_t> fitting_vertices;  // upstream's fitting subset
  std::vector<std::uint32_t> rigid_vertices;    // upstream's rigid subset (skin part)
  std::string provenance;  // where the data came from and its license (free text, may be empty)
  // The source's UV layout (optional; both empty in assets converted without it): `uvs` holds
  // (u, v) pairs, `triangle_uvs` the UV index of each triangle corner (same layout as
  // `triangles`). A vertex on a UV seam has several UVs, one per side.
  std::vector<float> uvs;
  std::vector<std::uint32_t> triangle_uvs;

  int triangle_count() const { return static_cast<int>(triangles.size() / 3); }
  // The UV layout spans `uv_tiles()` unit squares side by side (UDIM tiles 1001, 1002, ...:
  // the source puts the face in the first and the back of the head in the second).
  // atlas_uvs() maps them into one [0, 1] square, u divided by the tile count: the layout of a
  // texture atlas uv_tiles() times as wide as high, which exports and textures share.
  int uv_tiles() const;
  std::vector<float> atlas_uvs() const;
  // Index of an expression by name, or -1.
  int expression_index(std::string_view name) const;

  // One basis shape (3 * vertex_count floats, mm); k / j must be in range.
  std::span<const float> identity_mode(int k) const;
  std::span<const float> expression_shape(int j) const;

  // model = neutral + sum_k c_k * identity_k + sum_j w_j * expression_j, written to `out`
  // (3 * vertex_count floats). Shorter coefficient spans mean the remaining ones are zero;
  // extra coefficients are ignored. A shorter `out` evaluates only the first out.size() / 3
  // vertices (e.g. 3 * face_vertex_count for the face region alone). Zero coefficients are
  // skipped. Does not allocate.
  void evaluate(std::span<const float> identity_coeffs, std::span<const float> expression_weights,
                std::span<float> out) const;

  // out = base + sum_j w_j * expression_j, with `base` a precomputed face (typically
  // evaluate(c, {}, base) once per subject). Per-frame tracking then streams only the
  // expression basis instead of all 157 shapes. `out` may be the same buffer as `base`; the
  // same span rules as evaluate() apply (prefix of min(base, out) floats). Does not allocate.
  void evaluate_expressions(std::span<const float> base, std::span<const float> expression_weights,
                            std::span<float> out) const;
};

// Parses the compact asset (see data/README.md). Errors name what is wrong (bad magic,
// unsupported version, truncated at byte N, checksum mismatch) and say to re-run the converter.
Result<FaceModel> parse_face_model(std::span<const std::byte> bytes);

}  // namespace fb
