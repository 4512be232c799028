#include "algo/transfer/correspondence.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include "algo/transfer/alignment.hpp"

namespace fb {

namespace {

using Vec2 = Eigen::Vector2d;

double cross2(const Vec2& a, const Vec2& b) {
  return a.x() * b.y() - a.y() * b.x();
}

// Barycentric coordinates of p in triangle (a, b, c); NaN-free for degenerate triangles (they
// come back far outside).
Eigen::Vector3d barycentric(const Vec2& p, const Vec2& a, const Vec2& b, const Vec2& c) {
  const double area = cross2(b - a, c - a);
  if (std::abs(area) < 1e-18) return {-1e9, -1e9, -1e9};
  const double wb = cross2(p - a, c - a) / area, wc = cross2(b - a, p - a) / area;
  return {1.0 - wb - wc, wb, wc};
}

bool in_circumcircle(const Vec2& p, const Vec2& a, const Vec2& b, const Vec2& c) {
  const Vec2 ad = a - p, bd = b - p, cd = c - p;
  const double det = ad.squaredNorm() * cross2(bd, cd) - bd.squaredNorm() * cross2(ad, cd) +
                     cd.squaredNorm() * cross2(ad, bd);
  return cross2(b - a, c - a) > 0 ? det > 0 : det < 0;
}

}  // namespace

std::vector<std::uint32_t> delaunay(const std::vector<Vec2>& points) {
  const auto n = static_cast<std::uint32_t>(points.size());
  std::vector<Vec2> p = points;
  Vec2 lo = Vec2::Constant(1e300), hi = Vec2::Constant(-1e300);
  for (const Vec2& q : points) lo = lo.cwiseMin(q), hi = hi.cwiseMax(q);
  const double span = std::max((hi - lo).maxCoeff(), 1e-9) * 20;
  const Vec2 mid = (lo + hi) / 2;
  p.push_back(mid + Vec2(-span, -span));
  p.push_back(mid + Vec2(span, -span));
  p.push_back(mid + Vec2(0, span));
  std::vector<std::array<std::uint32_t, 3>> tris = {{n, n + 1, n + 2}};
  for (std::uint32_t i = 0; i < n; ++i) {
    std::map<std::pair<std::uint32_t, std::uint32_t>, int> edges;  // boundary of the cavity
    std::vector<std::array<std::uint32_t, 3>> keep;
    for (const auto& t : tris) {
      if (!in_circumcircle(p[i], p[t[0]], p[t[1]], p[t[2]])) {
        keep.push_back(t);
        continue;
      }
      for (int k = 0; k < 3; ++k) {
        const auto e = std::minmax(t[k], t[(k + 1) % 3]);
        ++edges[{e.first, e.second}];
      }
    }
    for (const auto& [e, count] : edges) {
      if (count != 1) continue;
      std::array<std::uint32_t, 3> t = {e.first, e.second, i};
      if (cross2(p[t[1]] - p[t[0]], p[t[2]] - p[t[0]]) < 0) std::swap(t[0], t[1]);
      keep.push_back(t);
    }
    tris = std::move(keep);
  }
  std::vector<std::uint32_t> out;
  for (const auto& t : tris)
    if (t[0] < n && t[1] < n && t[2] < n) out.insert(out.end(), t.begin(), t.end());
  return out;
}

namespace {

// Cylindrical coordinates about the vertical axis through `axis`: (angle * radius, height), so
// both are millimetres near the face.
struct Cylinder {
  Eigen::RowVector3d axis;
  double radius = 1;
  Vec2 operator()(const Eigen::RowVector3d& q) const {
    const Eigen::RowVector3d d = q - axis;
    return {std::atan2(d.x(), d.z()) * radius, d.y()};
  }
};

std::vector<Vec2> project(const Cylinder& cyl, const Points& p) {
  std::vector<Vec2> out(static_cast<std::size_t>(p.rows()));
  for (Eigen::Index i = 0; i < p.rows(); ++i) out[static_cast<std::size_t>(i)] = cyl(p.row(i));
  return out;
}

// Feature points plus the corners of the mesh's bounding box (1% margin): the parameterisation.
std::vector<Vec2> parameter_points(const std::vector<Vec2>& features,
                                   const std::vector<Vec2>& mesh) {
  Vec2 lo = Vec2::Constant(1e300), hi = Vec2::Constant(-1e300);
  for (const Vec2& q : mesh) lo = lo.cwiseMin(q), hi = hi.cwiseMax(q);
  const Vec2 m = (hi - lo) * 0.01;
  lo -= m, hi += m;
  std::vector<Vec2> out = features;
  out.insert(out.end(), {lo, Vec2(hi.x(), lo.y()), hi, Vec2(lo.x(), hi.y())});
  return out;
}

// Which parameterisation triangle holds q, and where: the one with the largest smallest weight.
std::pair<int, Eigen::Vector3d> locate(const Vec2& q, const std::vector<Vec2>& pts,
                                       const std::vector<std::uint32_t>& tris) {
  std::pair<int, Eigen::Vector3d> best{-1, Eigen::Vector3d::Constant(-1e300)};
  for (std::size_t t = 0; t + 2 < tris.size(); t += 3) {
    const Eigen::Vector3d w = barycentric(q, pts[tris[t]], pts[tris[t + 1]], pts[tris[t + 2]]);
    if (w.minCoeff() > best.second.minCoeff()) best = {static_cast<int>(t / 3), w};
    if (w.minCoeff() >= 0) break;
  }
  return best;
}

// A uniform grid of the source's triangles over the cylinder plane.
struct TriangleGrid {
  Vec2 lo, cell;
  int nx = 1, ny = 1;
  std::vector<std::vector<std::uint32_t>> cells;

  std::pair<int, int> index(const Vec2& q) const {
    const int x = std::clamp(static_cast<int>((q.x() - lo.x()) / cell.x()), 0, nx - 1);
    const int y = std::clamp(static_cast<int>((q.y() - lo.y()) / cell.y()), 0, ny - 1);
    return {x, y};
  }
};

TriangleGrid triangle_grid(const std::vector<Vec2>& uv, std::span<const std::uint32_t> tris,
                           double seam) {
  TriangleGrid g;
  Vec2 lo = Vec2::Constant(1e300), hi = Vec2::Constant(-1e300);
  for (const Vec2& q : uv) lo = lo.cwiseMin(q), hi = hi.cwiseMax(q);
  const int side = std::max(1, static_cast<int>(std::sqrt(tris.size() / 3.0 / 4.0)));
  g.lo = lo;
  g.nx = g.ny = side;
  g.cell = ((hi - lo) / side).cwiseMax(Vec2::Constant(1e-9));
  g.cells.resize(static_cast<std::size_t>(side * side));
  for (std::size_t t = 0; t + 2 < tris.size(); t += 3) {
    Vec2 a = uv[tris[t]], b = a;
    for (int k = 1; k < 3; ++k) a = a.cwiseMin(uv[tris[t + k]]), b = b.cwiseMax(uv[tris[t + k]]);
    if (b.x() - a.x() > seam) continue;  // wraps around the back of the cylinder
    const auto [x0, y0] = g.index(a);
    const auto [x1, y1] = g.index(b);
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x)
        g.cells[static_cast<std::size_t>(y * side + x)].push_back(static_cast<std::uint32_t>(t));
  }
  return g;
}

struct SourceSurface {
  const Points& points;
  std::span<const std::uint32_t> tris;
  std::vector<Vec2> uv;
  TriangleGrid grid;
};

// Barycentric coordinates of the point of triangle (a, b, c) nearest to p (Ericson, Real-Time
// Collision Detection 5.1.5).
Eigen::Vector3d closest_on_triangle(const Eigen::RowVector3d& p, const Eigen::RowVector3d& a,
                                    const Eigen::RowVector3d& b, const Eigen::RowVector3d& c) {
  const Eigen::RowVector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return {1, 0, 0};
  const Eigen::RowVector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return {0, 1, 0};
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double v = d1 / (d1 - d3);
    return {1 - v, v, 0};
  }
  const Eigen::RowVector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return {0, 0, 1};
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double w = d2 / (d2 - d6);
    return {1 - w, 0, w};
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return {0, 1 - w, w};
  }
  const double denom = va + vb + vc;
  if (std::abs(denom) < 1e-300) return {1, 0, 0};
  return {va / denom, vb / denom, vc / denom};
}

// The source point for a target vertex: among the source triangles within one grid cell of
// the cylinder position q (where the feature warp puts the vertex), the point nearest to the
// aligned target vertex `near` in 3D. The warp picks the neighbourhood, so folds of the
// projection (lips, eyelids, under the chin) and a different face shape do not mislead a
// global nearest-point search; the 3D search removes the warp's residual within it.
SurfacePoint source_point(const SourceSurface& s, const Vec2& q, const Eigen::RowVector3d& near) {
  SurfacePoint best;
  double best_score = std::numeric_limits<double>::infinity();
  const auto [cx, cy] = s.grid.index(q);
  for (int y = std::max(cy - 1, 0); y <= std::min(cy + 1, s.grid.ny - 1); ++y) {
    for (int x = std::max(cx - 1, 0); x <= std::min(cx + 1, s.grid.nx - 1); ++x) {
      for (std::uint32_t t : s.grid.cells[static_cast<std::size_t>(y * s.grid.nx + x)]) {
        const std::uint32_t a = s.tris[t], b = s.tris[t + 1], c = s.tris[t + 2];
        const Eigen::Vector3d w =
            closest_on_triangle(near, s.points.row(a), s.points.row(b), s.points.row(c));
        const Eigen::RowVector3d p =
            w[0] * s.points.row(a) + w[1] * s.points.row(b) + w[2] * s.points.row(c);
        const double score = (p - near).squaredNorm();
        if (score < best_score) best = {{a, b, c}, w, true}, best_score = score;
      }
    }
  }
  return best;
}

}  // namespace

Result<Correspondence> find_correspondence(const Points& source_neutral,
                                           std::span<const std::uint32_t> source_triangles,
                                           const Points& source_features,
                                           const Points& target_neutral,
                                           const Points& target_features) {
  if (source_features.rows() != target_features.rows() || source_features.rows() < 4)
    return fail("correspondence needs the same feature points (at least 4) on both faces");
  if (source_triangles.size() % 3 != 0 || source_triangles.empty())
    return fail("correspondence: the source needs triangles");
  auto align = align_similarity(target_features, source_features);
  if (!align) return align.failure();
  const Points target = align->apply(target_neutral);
  const Points target_feat = align->apply(target_features);
  // The axis runs through the middle of the source's bounding box (the head's centre, or behind
  // a face-only mesh): through the features' centroid it would pierce the face, where the
  // angle is ill-defined.
  const Eigen::RowVector3d mid =
      (source_neutral.colwise().minCoeff() + source_neutral.colwise().maxCoeff()) / 2;
  Cylinder cyl{mid, 1};
  double r = 0;
  for (Eigen::Index i = 0; i < source_features.rows(); ++i) {
    const Eigen::RowVector3d d = source_features.row(i) - cyl.axis;
    r += std::hypot(d.x(), d.z());
  }
  cyl.radius = std::max(r / static_cast<double>(source_features.rows()), 1e-9);
  SourceSurface src{source_neutral, source_triangles, project(cyl, source_neutral), {}};
  src.grid = triangle_grid(src.uv, source_triangles, M_PI * cyl.radius);
  const std::vector<Vec2> target_uv = project(cyl, target);
  const auto src_param = parameter_points(project(cyl, source_features), src.uv);
  const auto dst_param = parameter_points(project(cyl, target_feat), target_uv);
  const std::vector<std::uint32_t> tris = delaunay(src_param);
  Correspondence out;
  out.alignment = *align;
  out.points.resize(static_cast<std::size_t>(target.rows()));
  for (Eigen::Index v = 0; v < target.rows(); ++v) {
    const auto [t, w] = locate(target_uv[static_cast<std::size_t>(v)], dst_param, tris);
    SurfacePoint& sp = out.points[static_cast<std::size_t>(v)];
    if (t >= 0) {
      const auto k = static_cast<std::size_t>(3 * t);
      const Vec2 q =
          w[0] * src_param[tris[k]] + w[1] * src_param[tris[k + 1]] + w[2] * src_param[tris[k + 2]];
      sp = source_point(src, q, target.row(v));
    }
    out.unmatched += !sp.matched;
  }
  return out;
}

Transformations map_transformations(const Correspondence& c, const Transformations& source) {
  Transformations out(c.points.size(), Eigen::Matrix3d::Identity());
  for (std::size_t v = 0; v < c.points.size(); ++v) {
    const SurfacePoint& p = c.points[v];
    if (!p.matched) continue;
    out[v] = p.weights[0] * source[p.corners[0]] + p.weights[1] * source[p.corners[1]] +
             p.weights[2] * source[p.corners[2]];
  }
  return out;
}

Points map_points(const Correspondence& c, const Points& source) {
  Points out = Points::Zero(static_cast<Eigen::Index>(c.points.size()), 3);
  for (std::size_t v = 0; v < c.points.size(); ++v) {
    const SurfacePoint& p = c.points[v];
    if (!p.matched) continue;
    out.row(static_cast<Eigen::Index>(v)) = p.weights[0] * source.row(p.corners[0]) +
                                            p.weights[1] * source.row(p.corners[1]) +
                                            p.weights[2] * source.row(p.corners[2]);
  }
  return out;
}

}  // namespace fb
