// Smooth offsets along the face's normal for what the identity modes cannot hold (an
// out-of-span face's own bumps): Gaussian bumps centred on vertices of the mean face about
// `spacing_mm` apart, each moving the vertices near it along the mean face's normal. The
// neutral fit's PCA step solves their amplitudes together with the modes, each under its own
// prior, so a broad bump is paid for as a bump instead of by modes that slide the whole face
// along itself (docs/tuning.md, fifteenth session).
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "algo/facemodel/face_model.hpp"

namespace fb {

struct OffsetBasisOptions {
  double sigma_mm = 30.0;     // the bumps' Gaussian width
  double spacing_mm = 30.0;   // centres at least this far apart (farthest-point sampling)
  double reach_sigmas = 3.0;  // a bump ends here
  // Every bump fades to 0 at the eyes' and the mouth's landmark vertices (36-67): 0 within this
  // distance, full from twice it. Their rims have no depth; the modes and the landmarks place
  // them (0 = not held).
  double hold_features_mm = 5.0;
};

// Per vertex, the bumps that move it and their weight; the direction is `normal[v]`.
struct OffsetBasis {
  struct Entry {
    int bump;
    float weight;
  };
  int count = 0;
  std::vector<Eigen::Vector3f> normal;  // per vertex, unit (the basis' mesh, model frame)
  std::vector<std::uint32_t> first;     // vertex v's entries: [first[v], first[v + 1])
  std::vector<Entry> entries;
  std::span<const Entry> of(std::size_t v) const {
    return {entries.data() + first[v], entries.data() + first[v + 1]};
  }
};

// The basis on `mesh` (model frame, 3 floats a vertex, `model`'s topology), its centres picked
// among `centre_vertices`; every vertex of the mesh within reach moves.
OffsetBasis make_offset_basis(const FaceModel& model, std::span<const float> mesh,
                              std::span<const std::uint32_t> centre_vertices,
                              const OffsetBasisOptions& options = {});

// mesh += sum_k amplitude_mm[k] * bump_k.
void add_offsets(const OffsetBasis& basis, std::span<const double> amplitude_mm,
                 std::span<float> mesh);

}  // namespace fb
