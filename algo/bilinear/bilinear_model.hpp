// The bilinear face model (FaceWarehouse section 3.3): a reduced core tensor C_r
// (3V coordinates x id_knobs x exp_knobs) and the truncated mode factors U_id (training
// identities x id_knobs) and U_exp (expressions x exp_knobs), so that
//
//   V = C_r x_2 w_id^T x_3 w_exp^T                                                   (eq. 10)
//
// and the training subject i in expression e is approximately C_r x_2 U_id[i] x_3 U_exp[e].
// Units mm, the face model's frame and topology.
//
// The file format (serialize_bilinear_model / parse_bilinear_model, bytes only, no I/O) is
// documented in algo/bilinear/README.md: a 64-byte versioned header with a CRC-32 over
// everything after it, then fixed-order sections whose sizes follow from the header counts.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "algo/core/result.hpp"

namespace fb {

struct BilinearModel {
  int vertex_count = 0;       // V
  int face_vertex_count = 0;  // vertices 0..face_vertex_count-1 are the face region
  int id_knobs = 0;           // Kid
  int exp_knobs = 0;          // Kexp
  int identity_count = 0;     // training identities (rows of U_id)
  int expression_count = 0;   // expressions (rows of U_exp), 0 = neutral

  // Kexp * Kid blocks of 3V floats: block (b * Kid + a) is C_r[:, a, b].
  std::vector<float> core;
  std::vector<float> identity_factors;    // U_id, identity_count x Kid, row-major
  std::vector<float> expression_factors;  // U_exp, expression_count x Kexp, row-major
  // Eigenvalues of the mode-2 / mode-3 Gram matrices (squared singular values), descending,
  // all of them (identity_count / expression_count values): how much each knob carries.
  std::vector<float> identity_spectrum;
  std::vector<float> expression_spectrum;
  std::vector<std::string> expression_names;          // expression_count names, "neutral" first
  std::vector<std::uint32_t> triangles;               // 3 * T
  std::array<std::uint32_t, 68> landmark_vertices{};  // iBUG 68-point order
  std::string metadata;  // JSON text: how the model was built (source, seeds, knobs, times)

  int coordinate_count() const { return 3 * vertex_count; }
  std::span<const float> identity_row(int i) const;    // U_id[i], Kid floats
  std::span<const float> expression_row(int e) const;  // U_exp[e], Kexp floats

  // out (3V floats) = C_r x_2 w_id x_3 w_exp. w_id has Kid floats, w_exp Kexp floats.
  void evaluate(std::span<const float> w_id, std::span<const float> w_exp,
                std::span<float> out) const;
};

// The model file: bytes in, bytes out (files are written and read outside algo/).
std::vector<std::byte> serialize_bilinear_model(const BilinearModel& model);
// Checks magic, version, declared size against the buffer (truncation), CRC-32, counts and
// index ranges; never reads past the buffer. Errors say what is wrong and to rebuild the file
// with `facebooth model build`.
Result<BilinearModel> parse_bilinear_model(std::span<const std::byte> bytes);

}  // namespace fb
