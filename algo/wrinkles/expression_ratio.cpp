#include "algo/wrinkles/expression_ratio.hpp"

#include <algorithm>
#include <array>
#include <cmath>

namespace fb {

namespace {

// Catmull-Rom weights for a fraction t.
std::array<float, 4> cubic_weights(float t) {
  const float t2 = t * t, t3 = t2 * t;
  return {0.5f * (-t3 + 2 * t2 - t), 0.5f * (3 * t3 - 5 * t2 + 2), 0.5f * (-3 * t3 + 4 * t2 + t),
          0.5f * (t3 - t2)};
}

float sample(const FloatImage& src, double u, double v, bool cubic) {
  const int u0 = static_cast<int>(u), v0 = static_cast<int>(v);
  const auto au = static_cast<float>(u - u0), av = static_cast<float>(v - v0);
  if (!cubic || u0 < 1 || v0 < 1 || u0 + 2 >= src.width || v0 + 2 >= src.height)
    return (1 - av) * ((1 - au) * src.at(u0, v0) + au * src.at(u0 + 1, v0)) +
           av * ((1 - au) * src.at(u0, v0 + 1) + au * src.at(u0 + 1, v0 + 1));
  const auto wu = cubic_weights(au), wv = cubic_weights(av);
  float s = 0.0f;
  for (int j = 0; j < 4; ++j)
    for (int i = 0; i < 4; ++i)
      s += wu[static_cast<std::size_t>(i)] * wv[static_cast<std::size_t>(j)] *
           src.at(u0 - 1 + i, v0 - 1 + j);
  return s;
}

}  // namespace

Result<FloatImage> warp_neutral(const PinholeIntrinsics& k, const RasterBuffers& raster,
                                const MeshInCamera& neutral, const FloatImage& neutral_luminance,
                                bool cubic) {
  if (raster.width != k.width || raster.height != k.height)
    return fail("the expression ratio image: the raster is not the camera's size");
  const FloatImage& src = neutral_luminance;
  if (src.empty()) return fail("the expression ratio image: the neutral's frame is empty");
  const std::size_t nv = neutral.vertices.size();
  FloatImage out;
  out.resize(k.width, k.height);
  for (int y = 0; y < out.height; ++y)
    for (int x = 0; x < out.width; ++x) {
      out.at(x, y) = 0.0f;
      const std::size_t i = raster.index(x, y);
      const std::int32_t t = raster.triangle[i];
      if (t == kNoTriangle || 3 * static_cast<std::size_t>(t) + 2 >= neutral.triangles.size())
        continue;
      const std::uint32_t* tri = &neutral.triangles[3 * static_cast<std::size_t>(t)];
      if (tri[0] >= nv || tri[1] >= nv || tri[2] >= nv)
        return fail("the expression ratio image: the neutral mesh has another topology");
      const float b1 = raster.bary1[i], b2 = raster.bary2[i], b0 = 1.0f - b1 - b2;
      const Eigen::Vector3f p = b0 * neutral.vertices[tri[0]] + b1 * neutral.vertices[tri[1]] +
                                b2 * neutral.vertices[tri[2]];
      if (!(p.z() > 1.0f)) continue;
      const double u = k.fx * p.x() / p.z() + k.cx, v = k.fy * p.y() / p.z() + k.cy;
      if (u < 0 || v < 0 || u > src.width - 2 || v > src.height - 2) continue;
      out.at(x, y) = sample(src, u, v, cubic);
    }
  return out;
}

FloatImage ratio_image(const FloatImage& luminance, const FloatImage& warped, float min_warped) {
  FloatImage out = luminance;
  if (warped.width != luminance.width || warped.height != luminance.height) return out;
  for (std::size_t i = 0; i < out.pixels.size(); ++i)
    if (warped.pixels[i] > min_warped)
      out.pixels[i] = 0.5f * luminance.pixels[i] / warped.pixels[i];
  return out;
}

std::vector<Eigen::Vector3f> region_normals(const RasterBuffers& raster, const MeshInCamera& mesh,
                                            std::span<const PixelRect> regions) {
  std::vector<Eigen::Vector3f> out;
  const std::size_t nt = mesh.triangles.size() / 3;
  for (const auto& r : regions) {
    Eigen::Vector3f sum = Eigen::Vector3f::Zero();
    for (int y = std::max(0, r.y0); y < std::min(raster.height, r.y1); ++y)
      for (int x = std::max(0, r.x0); x < std::min(raster.width, r.x1); ++x) {
        const std::int32_t t = raster.triangle[raster.index(x, y)];
        if (t == kNoTriangle || static_cast<std::size_t>(t) >= nt) continue;
        const std::uint32_t* tri = &mesh.triangles[3 * static_cast<std::size_t>(t)];
        const Eigen::Vector3f n = (mesh.vertices[tri[1]] - mesh.vertices[tri[0]])
                                      .cross(mesh.vertices[tri[2]] - mesh.vertices[tri[0]]);
        // Towards the camera, whatever the winding.
        if (n.norm() > 0) sum += (n.z() > 0 ? -n : n).normalized();
      }
    out.push_back(sum.norm() > 0 ? Eigen::Vector3f(sum.normalized())
                                 : Eigen::Vector3f(0.0f, 0.0f, -1.0f));
  }
  return out;
}

SkinLight skin_light_for(const Eigen::Vector3f& normal, const Eigen::Vector3f& to_light,
                         const SkinLight& base) {
  const Eigen::Vector3f n = normal.normalized(), l = to_light.normalized();
  const Eigen::Vector3f tx = (Eigen::Vector3f::UnitX() - n * n.x()).normalized();
  Eigen::Vector3f ty = Eigen::Vector3f::UnitY() - n * n.y();
  ty = (ty - tx * tx.dot(ty)).normalized();
  SkinLight out = base;
  out.to_light = Eigen::Vector3f(l.dot(tx), l.dot(ty), l.dot(n));
  return out;
}

}  // namespace fb
