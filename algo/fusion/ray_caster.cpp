#include "algo/fusion/ray_caster.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "algo/fusion/preprocess.hpp"

namespace fb {
namespace {

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

void RayCaster::cast(const TsdfVolume& volume, const PoseF& world_from_camera,
                     const Image<float>* hint, bool hint_is_raw, bool full_search, MapLevel& out,
                     ParallelRunner& runner) const {
  const LevelIntrinsics& k = out.k;
  const FaceBox& box = out.box;
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

  runner.run([&](int part, int parts) {
    int y0, y1;
    ParallelRunner::split(box.y, box.y + box.height, part, parts, y0, y1);
    for (int y = y0; y < y1; ++y) {
      const float ry = (static_cast<float>(y) - k.cy) * ify;
      for (int x = box.x; x < box.x + box.width; ++x) {
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
        float found = 0.0f;
        // Two passes: from the hint (cheap, a few steps), then from the volume entry if the
        // hint started behind the surface (or, for full searches, found nothing). A hint
        // outside the volume (background) means there is nothing to find for the model view.
        bool behind = false;
        for (int pass = 0; pass < 2 && found == 0.0f; ++pass) {
          float t = t_enter;
          float t_end = t_exit;
          if (pass == 1 && !behind && !full_search) break;
          if (pass == 0) {
            if (h <= 0.0f) continue;
            // start_margin in front: beyond 3 sigma of the hint's noise, yet only one or two
            // TSDF-sized steps from the surface.
            t = std::max(t_enter, h - start_margin);
            t_end = std::min(t_exit, h + 3.0f * mu);
          } else if (!full_search) {
            // The hint started behind the surface: the model is in front of this frame's depth
            // by more than the margin; look up to 2 mu in front (beyond that the tracker's
            // association gate would reject the pair anyway).
            t = std::max(t_enter, h - 2.0f * mu);
            t_end = std::min(t_exit, h);
          }
          float prev_t = -1.0f, prev_f = 0.0f;
          bool first = true;
          while (t <= t_end) {
            const Sample s = nearest(volume, go + t * gd);
            if (!s.seen) {
              prev_t = -1.0f;
              first = false;
              t += free_step;
              continue;
            }
            if (s.f < 0.0f) {
              if (prev_t >= 0.0f) {
                // The nearest voxel says "behind"; the trilinear TSDF decides. The nearest
                // voxel's centre can lie up to half a voxel beyond t, so taking its sign as the
                // crossing would pull every surface towards the camera.
                float fb = 0.0f;
                const bool fb_ok = volume.trilinear(go + t * gd, fb);
                if (fb_ok && fb >= 0.0f) {
                  prev_t = t;
                  prev_f = fb;
                  t += min_step;
                  continue;
                }
                float fa;
                float ta = prev_t, tb = t;
                bool fa_ok = volume.trilinear(go + ta * gd, fa);
                if (fa_ok && fa <= 0.0f) {
                  // Crossed before prev_t (its nearest voxel was positive): one step back.
                  tb = ta;
                  fb = fa;
                  ta = std::max(t_enter, ta - min_step);
                  fa_ok = volume.trilinear(go + ta * gd, fa) && fa > 0.0f;
                }
                if (fa_ok && fb_ok && fa > 0.0f && fb < 0.0f) {
                  // Regula falsi on the trilinear TSDF, refined once inside the bracket.
                  float tm = ta + (tb - ta) * fa / (fa - fb);
                  float fm;
                  if (volume.trilinear(go + tm * gd, fm)) {
                    if (fm > 0.0f) {
                      ta = tm;
                      fa = fm;
                    } else {
                      tb = tm;
                      fb = fm;
                    }
                    if (fa > fb) tm = ta + (tb - ta) * fa / (fa - fb);
                  }
                  found = tm;
                } else {
                  found = prev_t + (t - prev_t) * prev_f / (prev_f - s.f);
                }
                break;
              }
              if (first && pass == 0) {  // the hint started behind the surface
                behind = true;
                break;
              }
              // Behind a surface seen from elsewhere (back side): keep marching.
              prev_t = -1.0f;
              t += min_step;
              first = false;
              continue;
            }
            first = false;
            prev_t = t;
            prev_f = s.f;
            // The TSDF is the (projective) distance to the surface in units of mu.
            t += std::max(min_step, 0.8f * s.f * mu);
          }
        }
        if (found > 0.0f) {
          depth = found;
          vertex = ray * found;
        }
      }
    }
  });
  runner.run([&](int part, int parts) {
    int y0, y1;
    ParallelRunner::split(box.y, box.y + box.height, part, parts, y0, y1);
    compute_normals_from_vertices(out, options_.normal_max_depth_jump_mm, y0, y1);
  });
}

void subsample_model_levels(ModelView& view) {
  for (int l = 1; l < kPyramidLevels; ++l) {
    const MapLevel& fine = view.levels[l - 1];
    MapLevel& coarse = view.levels[l];
    const FaceBox& b = coarse.box;
    for (int y = b.y; y < b.y + b.height; ++y) {
      for (int x = b.x; x < b.x + b.width; ++x) {
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
