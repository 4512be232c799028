#include "algo/fusion/ray_caster.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "algo/fusion/multiversion.hpp"
#include "algo/fusion/preprocess.hpp"

namespace fb {
namespace {

// The marcher's step (a fraction of the distance f mu to the surface) and its regula falsi
// steps inside the bracket; a second step changed neither the fused error nor the bias (5 seeds).
constexpr float kStepFraction = 0.8f;
constexpr int kRefinements = 1;

// Ray parameter range [t0, t1] (camera depth) where o + t d lies inside [0, hi]^3.
inline bool clip_ray(const Eigen::Vector3f& o, const Eigen::Vector3f& d, float hi, float& t0,
                     float& t1) {
  t0 = 0.0f;
  t1 = std::numeric_limits<float>::max();
  for (int i = 0; i < 3; ++i) {
    if (std::abs(d[i]) < 1e-9f) {
      if (o[i] < 0.0f || o[i] > hi) return false;
      continue;
    }
    float a = (0.0f - o[i]) / d[i], b = (hi - o[i]) / d[i];
    if (a > b) std::swap(a, b);
    t0 = std::max(t0, a);
    t1 = std::min(t1, b);
  }
  return t0 < t1;
}

struct Sample {
  bool seen;
  float f;
};

inline Sample nearest(const TsdfVolume& vol, const Eigen::Vector3f& g) {
  const int x = static_cast<int>(g.x() + 0.5f), y = static_cast<int>(g.y() + 0.5f),
            z = static_cast<int>(g.z() + 0.5f);
  const int n = vol.resolution();
  if (x < 0 || y < 0 || z < 0 || x >= n || y >= n || z >= n) return {false, 1.0f};
  const Voxel& v = vol.at(x, y, z);
  return {v.weight() > 0, static_cast<float>(v.tsdf()) * (1.0f / TsdfVolume::kTsdfScale)};
}

}  // namespace

FB_CLONE_X86_64_V3 void RayCaster::cast(const TsdfVolume& volume, const RigidPoseF& world_from_camera,
                                        const Image<float>* hint, bool hint_is_raw,
                                        bool full_search, MapLevel& out,
                                        ParallelRunner& runner) const {
  const LevelIntrinsics& k = out.k;
  const PixelRect& box = out.box;
  const float vs = volume.voxel_size();
  const float inv_vs = 1.0f / vs;
  const float mu = options_.truncation_mm;
  const float hi = static_cast<float>(volume.resolution() - 1);
  // Grid coordinates along the ray: g(t) = go + t * gd(u, v), t = camera depth in mm.
  const Eigen::Vector3f go = (world_from_camera.t - volume.origin()) * inv_vs -
                             Eigen::Vector3f::Constant(0.5f);  // voxel centres at integers
  const Eigen::Matrix3f gr = world_from_camera.r * inv_vs;
  const float ifx = 1.0f / k.fx, ify = 1.0f / k.fy;
  const float min_step = 0.5f * vs, free_step = 0.8f * mu;
  // Raw depth (Kinect noise ~1.5 mm at face range) needs 0.75 mu; filtered depth 0.4 mu.
  const float start_margin = (hint_is_raw ? 0.75f : 0.4f) * mu;

  // First zero crossing of the trilinear TSDF along g(t) = o + t d in [t, t_end], 0 if none.
  // Every sample is trilinear: the nearest voxel's value is that of a point up to half a voxel
  // away, and on a noisy, thin model (the first frames) stepping and bracketing by it landed
  // beyond the first crossing often enough to put the whole model ~0.15 mm behind the surface,
  // which the tracker then copied into every pose. Steps are 0.8 f mu in front of the surface
  // (f is the projective distance in units of mu), at least half a voxel; the bracket
  // [last f >= 0, first f < 0] is refined by one regula falsi step and a final secant. `behind` is
  // set when the first sample already lies behind a surface (the hint started too deep).
  auto march = [&](const Eigen::Vector3f& o, const Eigen::Vector3f& d, float t, float t_end,
                   bool detect_behind, bool& behind) FB_INLINE -> float {
    float prev_t = -1.0f, prev_f = 0.0f;
    bool first = true;
    while (t <= t_end) {
      float f;
      if (!volume.trilinear(o + t * d, f)) {
        // A corner is unseen: free space outside the band, or the edge of what was observed.
        prev_t = -1.0f;
        first = false;
        t += nearest(volume, o + t * d).seen ? min_step : free_step;
        continue;
      }
      if (f >= 0.0f) {
        prev_t = t;
        prev_f = f;
        first = false;
        t += std::max(min_step, kStepFraction * f * mu);
        continue;
      }
      if (prev_t < 0.0f) {
        if (first && detect_behind) {
          behind = true;
          return 0.0f;
        }
        // Behind a surface seen from elsewhere (back side), or entered from unseen voxels.
        first = false;
        t += min_step;
        continue;
      }
      float ta = prev_t, fa = prev_f, tb = t, fb = f;
      for (int i = 0; i < kRefinements; ++i) {
        const float tm = ta + (tb - ta) * fa / (fa - fb);
        float fm;
        if (!volume.trilinear(o + tm * d, fm)) return tm;
        if (fm >= 0.0f) {
          ta = tm;
          fa = fm;
        } else {
          tb = tm;
          fb = fm;
        }
      }
      return ta + (tb - ta) * fa / (fa - fb);
    }
    return 0.0f;
  };

  // Called directly on one thread, so that it is part of this function's x86-64-v3 build.
  auto cast_rows = [&](int part, int parts) FB_INLINE {
    int y0, y1;
    ParallelRunner::split(box.y0, box.y1, part, parts, y0, y1);
    for (int y = y0; y < y1; ++y) {
      const float ry = (static_cast<float>(y) - k.cy) * ify;
      for (int x = box.x0; x < box.x1; ++x) {
        const Eigen::Vector3f ray((static_cast<float>(x) - k.cx) * ifx, ry, 1.0f);
        const Eigen::Vector3f gd = gr * ray;
        Eigen::Vector3f& vertex = out.vertices.at(x, y);
        float& depth = out.depth.at(x, y);
        float h = hint ? hint->at(x, y) : 0.0f;
        if (h <= 0.0f) h = depth;
        vertex.setZero();
        depth = 0.0f;
        if (h <= 0.0f && !full_search) continue;
        float t_enter, t_exit;
        if (!clip_ray(go, gd, hi, t_enter, t_exit)) continue;
        // Two passes: from the hint (cheap, a few steps), then from the volume entry if the
        // hint started behind the surface (or, for full searches, found nothing). A hint
        // outside the volume (background) means there is nothing to find for the model view.
        float found = 0.0f;
        bool behind = false;
        for (int pass = 0; pass < 2 && found == 0.0f; ++pass) {
          float t = t_enter;
          float t_end = t_exit;
          if (pass == 0) {
            if (h <= 0.0f) continue;
            // start_margin in front: beyond 3 sigma of the hint's noise, yet only one or two
            // TSDF-sized steps from the surface.
            t = std::max(t_enter, h - start_margin);
            t_end = std::min(t_exit, h + 3.0f * mu);
          } else if (!full_search) {
            if (!behind) break;
            // The hint started behind the surface: the model is in front of this frame's depth
            // by more than the margin; look up to 2 mu in front (beyond that the tracker's
            // association gate would reject the pair anyway).
            t = std::max(t_enter, h - 2.0f * mu);
            t_end = std::min(t_exit, h);
          }
          found = march(go, gd, t, t_end, pass == 0, behind);
        }
        if (found > 0.0f) {
          depth = found;
          vertex = ray * found;
        }
      }
    }
  };
  if (runner.parts() > 1) {
    runner.run(cast_rows);
  } else {
    cast_rows(0, 1);
  }
  runner.run([&](int part, int parts) {
    int y0, y1;
    ParallelRunner::split(box.y0, box.y1, part, parts, y0, y1);
    compute_normals_from_vertices(out, options_.normal_max_depth_jump_mm, y0, y1);
  });
}

void subsample_model_levels(ModelView& view) {
  for (int l = 1; l < kPyramidLevels; ++l) {
    const MapLevel& fine = view.levels[l - 1];
    MapLevel& coarse = view.levels[l];
    const PixelRect& b = coarse.box;
    for (int y = b.y0; y < b.y1; ++y) {
      for (int x = b.x0; x < b.x1; ++x) {
        const int fx = std::min(2 * x, fine.vertices.width - 1);
        const int fy = std::min(2 * y, fine.vertices.height - 1);
        coarse.vertices.at(x, y) = fine.vertices.at(fx, fy);
        coarse.normals.at(x, y) = fine.normals.at(fx, fy);
        coarse.depth.at(x, y) = fine.depth.at(fx, fy);
      }
    }
  }
}

}  // namespace fb
