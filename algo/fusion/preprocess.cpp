#include "algo/fusion/preprocess.hpp"

#include <algorithm>
#include <cmath>

namespace fb {

void DepthPreprocessor::configure(const FusionOptions& options) {
  options_ = options;
  gate_min_ = options.min_depth_mm;
  gate_max_ = options.max_depth_mm;
  const int r = std::max(0, options.bilateral_radius_px);
  const float ss = std::max(0.1f, options.bilateral_sigma_space_px);
  spatial_weights_.assign(static_cast<std::size_t>((2 * r + 1) * (2 * r + 1)), 0.0f);
  for (int dy = -r; dy <= r; ++dy)
    for (int dx = -r; dx <= r; ++dx)
      spatial_weights_[(dy + r) * (2 * r + 1) + (dx + r)] =
          std::exp(-static_cast<float>(dx * dx + dy * dy) / (2.0f * ss * ss));
  // Range weights cut off at 3 sigma: farther neighbours belong to another surface.
  const float sr = std::max(0.1f, options.bilateral_sigma_depth_mm);
  const int n = static_cast<int>(std::ceil(3.0f * sr / kRangeStep)) + 1;
  range_weights_.resize(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) {
    const float d = static_cast<float>(i) * kRangeStep;
    range_weights_[i] = std::exp(-d * d / (2.0f * sr * sr));
  }
}

namespace {

inline bool valid_vertex(const Eigen::Vector3f& v) {
  return v.z() > 0.0f;
}

// Edge-aware 2x2 block average: pixels further than `jump` from the block's first valid pixel
// are left out, so silhouettes do not produce phantom depths between face and background.
void downsample_level(const MapLevel& fine, MapLevel& coarse, float jump, int y0, int y1) {
  const PixelRect& b = coarse.box;
  for (int y = y0; y < y1; ++y) {
    for (int x = b.x0; x < b.x1; ++x) {
      const int fx = 2 * x, fy = 2 * y;
      float ref = 0.0f, sum = 0.0f;
      int count = 0;
      for (int i = 0; i < 4; ++i) {
        const int sx = fx + (i & 1), sy = fy + (i >> 1);
        if (sx >= fine.depth.width || sy >= fine.depth.height) continue;
        const float d = fine.depth.at(sx, sy);
        if (d <= 0.0f) continue;
        if (count == 0) ref = d;
        if (std::abs(d - ref) > jump) continue;
        sum += d;
        ++count;
      }
      coarse.depth.at(x, y) = count > 0 ? sum / static_cast<float>(count) : 0.0f;
    }
  }
}

}  // namespace

void compute_vertex_map(MapLevel& level, int y0, int y1) {
  const LevelIntrinsics& k = level.k;
  const PixelRect& b = level.box;
  const float ifx = 1.0f / k.fx, ify = 1.0f / k.fy;
  for (int y = y0; y < y1; ++y) {
    const float* d = &level.depth.at(0, y);
    Eigen::Vector3f* v = &level.vertices.at(0, y);
    for (int x = b.x0; x < b.x1; ++x) {
      const float z = d[x];
      v[x] = z > 0.0f ? Eigen::Vector3f((static_cast<float>(x) - k.cx) * ifx * z,
                                        (static_cast<float>(y) - k.cy) * ify * z, z)
                      : Eigen::Vector3f::Zero();
    }
  }
}

void compute_normals_from_vertices(MapLevel& level, float max_jump_mm, int y0, int y1) {
  const PixelRect& b = level.box;
  const int w = level.vertices.width, h = level.vertices.height;
  for (int y = y0; y < y1; ++y) {
    for (int x = b.x0; x < b.x1; ++x) {
      Eigen::Vector3f& n = level.normals.at(x, y);
      n.setZero();
      const Eigen::Vector3f& c = level.vertices.at(x, y);
      if (!valid_vertex(c) || x == 0 || y == 0 || x + 1 >= w || y + 1 >= h) continue;
      // Central differences; fall back to one-sided ones at holes and edges of the data.
      const Eigen::Vector3f& l = level.vertices.at(x - 1, y);
      const Eigen::Vector3f& r = level.vertices.at(x + 1, y);
      const Eigen::Vector3f& u = level.vertices.at(x, y - 1);
      const Eigen::Vector3f& dn = level.vertices.at(x, y + 1);
      const bool lv = valid_vertex(l) && std::abs(l.z() - c.z()) < max_jump_mm;
      const bool rv = valid_vertex(r) && std::abs(r.z() - c.z()) < max_jump_mm;
      const bool uv = valid_vertex(u) && std::abs(u.z() - c.z()) < max_jump_mm;
      const bool dv = valid_vertex(dn) && std::abs(dn.z() - c.z()) < max_jump_mm;
      if (!(lv || rv) || !(uv || dv)) continue;
      const Eigen::Vector3f dx = (rv ? r : c) - (lv ? l : c);
      const Eigen::Vector3f dy = (dv ? dn : c) - (uv ? u : c);
      Eigen::Vector3f nn = dy.cross(dx);  // points towards the camera for x right, y down
      const float len = nn.norm();
      if (len <= 0.0f) continue;
      nn /= len;
      if (nn.dot(c) > 0.0f) nn = -nn;
      n = nn;
    }
  }
}

void DepthPreprocessor::run(const DepthImage& depth, DepthPyramid& pyramid,
                            ParallelRunner& runner) const {
  MapLevel& l0 = pyramid.levels[0];
  const PixelRect box = l0.box;
  const float dmin = gate_min_, dmax = gate_max_;
  // Gate the raw depth into float (inside the box only; outside stays 0 from allocate()).
  // The plane gate on the ray through (x, y) at depth d: d * (n . ray) <= offset, with
  // n . ray = ax * x + (ay * y + c) linear along the row.
  const LevelIntrinsics& k = l0.k;
  const float ax = plane_gate_ ? plane_normal_.x() / k.fx : 0.0f;
  const float ay = plane_gate_ ? plane_normal_.y() / k.fy : 0.0f;
  const float c0 = plane_gate_ ? plane_normal_.z() - ax * k.cx - ay * k.cy : 0.0f;
  const float offset = plane_gate_ ? plane_offset_ : 1.0f;
  int valid = 0;
  for (int y = box.y0; y < box.y1; ++y) {
    const std::uint16_t* src = &depth.pixels[static_cast<std::size_t>(y) * depth.width];
    float* dst = &pyramid.raw.at(0, y);
    const float row = ay * static_cast<float>(y) + c0;
    for (int x = box.x0; x < box.x1; ++x) {
      const float d = static_cast<float>(src[x]);
      const bool ok = d >= dmin && d <= dmax && d * (ax * static_cast<float>(x) + row) <= offset;
      dst[x] = ok ? d : 0.0f;
      valid += ok;
    }
  }
  pyramid.valid_pixels = valid;

  const int r = std::max(0, options_.bilateral_radius_px);
  const float inv_step = 1.0f / kRangeStep;
  const int nrange = static_cast<int>(range_weights_.size());
  const float jump = options_.normal_max_depth_jump_mm;
  runner.run([&](int part, int parts) {
    int y0, y1;
    ParallelRunner::split(box.y0, box.y1, part, parts, y0, y1);
    const Image<float>& raw = pyramid.raw;
    for (int y = y0; y < y1; ++y) {
      for (int x = box.x0; x < box.x1; ++x) {
        const float c = raw.at(x, y);
        float out = 0.0f;
        if (c > 0.0f) {
          float sw = 0.0f, s = 0.0f;
          for (int dy = -r; dy <= r; ++dy) {
            const int yy = y + dy;
            if (yy < box.y0 || yy >= box.y1) continue;
            const float* row = &raw.at(0, yy);
            const float* ws = &spatial_weights_[(dy + r) * (2 * r + 1) + r];
            for (int dx = -r; dx <= r; ++dx) {
              const int xx = x + dx;
              if (xx < box.x0 || xx >= box.x1) continue;
              const float d = row[xx];
              if (d <= 0.0f) continue;
              const int ri = static_cast<int>(std::abs(d - c) * inv_step);
              if (ri >= nrange) continue;
              const float wgt = ws[dx] * range_weights_[ri];
              sw += wgt;
              s += wgt * d;
            }
          }
          out = s / sw;
        }
        l0.depth.at(x, y) = out;
      }
    }
  });
  for (int level = 1; level < kPyramidLevels; ++level) {
    const MapLevel& fine = pyramid.levels[level - 1];
    MapLevel& coarse = pyramid.levels[level];
    downsample_level(fine, coarse, 3.0f * options_.bilateral_sigma_depth_mm, coarse.box.y0,
                     coarse.box.y1);
  }
  runner.run([&](int part, int parts) {
    for (int level = 0; level < kPyramidLevels; ++level) {
      MapLevel& m = pyramid.levels[level];
      int y0, y1;
      ParallelRunner::split(m.box.y0, m.box.y1, part, parts, y0, y1);
      compute_vertex_map(m, y0, y1);
    }
  });
  // Normals read neighbouring rows, so they run after every vertex row exists; then the depth
  // to fuse: raw (or filtered) depth where the surface is seen at a usable angle.
  const float cos_max = std::cos(options_.integrate_max_angle_deg * 3.14159265f / 180.0f);
  const bool gate_angle = options_.integrate_max_angle_deg < 90.0f;
  runner.run([&](int part, int parts) {
    for (int level = 0; level < kPyramidLevels; ++level) {
      MapLevel& m = pyramid.levels[level];
      int y0, y1;
      ParallelRunner::split(m.box.y0, m.box.y1, part, parts, y0, y1);
      compute_normals_from_vertices(m, jump * static_cast<float>(1 << level), y0, y1);
    }
    int y0, y1;
    ParallelRunner::split(box.y0, box.y1, part, parts, y0, y1);
    const MapLevel& m0 = pyramid.levels[0];
    const Image<float>& source = options_.integrate_filtered_depth ? m0.depth : pyramid.raw;
    for (int y = y0; y < y1; ++y) {
      for (int x = box.x0; x < box.x1; ++x) {
        const float d = source.at(x, y);
        float out = d;
        if (gate_angle && d > 0.0f) {
          const Eigen::Vector3f& n = m0.normals.at(x, y);
          const Eigen::Vector3f& v = m0.vertices.at(x, y);
          // cos = -n . v / |v|, compared without the square root: (n . v)^2 >= cos^2 |v|^2.
          const float nv = -n.dot(v);
          if (!(nv > 0.0f && nv * nv >= cos_max * cos_max * v.squaredNorm())) out = 0.0f;
        }
        pyramid.fused.at(x, y) = out;
      }
    }
  });
}

}  // namespace fb
