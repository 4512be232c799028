// Tracking engine: frame-to-model projective point-to-plane ICP, coarse to fine over the
// pyramid, against the ray-cast model view. Each iteration linearises
//   r_i = n_i . (T p_i - m_i),  T <- exp(xi) T,  J_i = [ (T p_i) x n_i ; n_i ]
// and solves the 6x6 normal equations (Huber-weighted) in double.
#pragma once

#include "algo/fusion/fusion_maps.hpp"
#include "algo/fusion/parallel.hpp"

namespace fb {

struct IcpResult {
  RigidPoseF world_from_camera;
  int inliers = 0;      // at level 0, last iteration
  int candidates = 0;   // valid input points at level 0
  float rms_mm = 0.0f;  // of the inliers at level 0
  int iterations = 0;
  bool solved = false;  // every linear solve was well conditioned
};

class IcpTracker {
 public:
  void configure(const FusionOptions& options);
  IcpResult track(const DepthPyramid& input, const ModelView& model, const RigidPoseF& initial,
                  ParallelRunner& runner) const;

 private:
  FusionOptions options_;
  float cos_normal_ = 0.8f;
};

}  // namespace fb
