// Preprocessing engine: depth gating, bilateral filter (inside the face box only), a 3-level
// pyramid by edge-aware 2x2 averaging, and vertex + normal maps on every level.
#pragma once

#include <vector>

#include "algo/core/image.hpp"
#include "algo/fusion/fusion_maps.hpp"
#include "algo/fusion/parallel.hpp"

namespace fb {

class DepthPreprocessor {
 public:
  void configure(const FusionOptions& options);
  // Depths kept this frame (the options' range after configure()): fusion narrows it to the
  // band around a detected face, so nearer hands, chest or desk never enter the pyramid.
  void set_depth_gate(float min_mm, float max_mm) {
    gate_min_ = min_mm;
    gate_max_ = max_mm;
  }
  // Camera points p with normal . p > offset are dropped too (the cut below the chin).
  void set_plane_gate(const Eigen::Vector3f& normal, float offset) {
    plane_normal_ = normal;
    plane_offset_ = offset;
    plane_gate_ = true;
  }
  void clear_plane_gate() { plane_gate_ = false; }
  // Fills `pyramid` (already allocated for this image size and face box) from `depth`.
  void run(const DepthImage& depth, DepthPyramid& pyramid, ParallelRunner& runner) const;

 private:
  FusionOptions options_;
  float gate_min_ = 0.0f, gate_max_ = 0.0f;
  bool plane_gate_ = false;
  Eigen::Vector3f plane_normal_ = Eigen::Vector3f::Zero();
  float plane_offset_ = 0.0f;
  std::vector<float> spatial_weights_;  // (2r+1)^2
  std::vector<float> range_weights_;    // exp(-d^2 / 2 sigma^2) sampled every kRangeStep mm
  static constexpr float kRangeStep = 0.25f;
};

// Vertex map (camera frame) of one level from its depth, rows [y0, y1) of the box.
void compute_vertex_map(MapLevel& level, int y0, int y1);
// Normals only, from an existing vertex map (used for the ray-cast model view).
void compute_normals_from_vertices(MapLevel& level, float max_jump_mm, int y0, int y1);

}  // namespace fb
