// A small but complete face model (5 vertices, 2 identity modes, 3 expressions) with
// deterministic contents: for format and evaluation tests that must not depend on the asset,
// and for the fuzz targets' seed corpora (tests/fuzz/fuzz_seeds.cpp). Header-only, no GoogleTest.
#pragma once

#include "algo/facemodel/face_model.hpp"

namespace fb::test {

inline FaceModel make_tiny_model() {
  FaceModel m;
  m.vertex_count = 5;
  m.face_vertex_count = 3;
  m.identity_count = 2;
  m.expression_count = 3;
  m.fitting_expression_count = 2;
  const int n3 = 3 * m.vertex_count;
  for (int i = 0; i < n3; ++i) m.neutral.push_back(10.0f * static_cast<float>(i) - 7.5f);
  for (int k = 0; k < m.identity_count * n3; ++k) {
    m.identity_basis.push_back(0.25f * static_cast<float>((k * 7) % 11) - 1.0f);
  }
  for (int k = 0; k < m.expression_count * n3; ++k) {
    m.expression_basis.push_back(0.5f * static_cast<float>((k * 5) % 13) - 3.0f);
  }
  m.expression_names = {"jawOpen", "mouthSmile_L", "PupilDilate_L"};
  m.triangles = {0, 1, 2, 0, 2, 3, 2, 3, 4};
  for (std::uint32_t i = 0; i < 68; ++i) m.landmark_vertices[i] = i % 5;
  m.rigid_landmarks = {0, 36, 67};
  m.right_jawline = {1, 2};
  m.left_jawline = {3};
  m.right_extended_jawline = {0, 1, 2};
  m.left_extended_jawline = {3, 4};
  m.fitting_vertices = {0, 1, 2};
  m.rigid_vertices = {4};
  m.provenance = "tiny test model";
  m.uvs = {0.0f, 0.0f, 1.0f, 0.0f, 0.0f, 1.0f, 1.0f, 1.0f};
  m.triangle_uvs = {0, 1, 2, 0, 2, 3, 2, 3, 1};
  return m;
}

}  // namespace fb::test
