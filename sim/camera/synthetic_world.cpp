#include "sim/camera/synthetic_world.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include <Eigen/Geometry>

#include "algo/core/mix64.hpp"

namespace fb {
namespace {

// Counter-based uniforms in (0, 1): a subject's world is the same on every build.
double uniform(std::uint64_t seed, std::uint64_t stream, std::uint64_t k) {
  const auto bits = mix64(mix64(seed * 0x9E3779B97F4A7C15ull + (stream << 48)) + k);
  return (static_cast<double>(bits >> 11) + 0.5) * 0x1.0p-53;
}

double gaussian(std::uint64_t seed, std::uint64_t stream, std::uint64_t k) {
  const double u1 = uniform(seed, stream, 2 * k), u2 = uniform(seed, stream, 2 * k + 1);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
}

constexpr std::uint64_t kStreamBumps = 11, kStreamHair = 12, kStreamLight = 13, kStreamTexture = 14,
                        kStreamProps = 15, kStreamMaterial = 16, kStreamAsym = 17;

float smooth01(float x) {
  x = std::clamp(x, 0.0f, 1.0f);
  return x * x * (3.0f - 2.0f * x);
}

// Value noise in [-1, 1] on the integer lattice, smoothly interpolated.
float value_noise(std::uint64_t seed, const Eigen::Vector3f& p) {
  const Eigen::Vector3f f = p.array().floor();
  const Eigen::Vector3f t = p - f;
  const auto ix = static_cast<std::int64_t>(f.x()), iy = static_cast<std::int64_t>(f.y()),
             iz = static_cast<std::int64_t>(f.z());
  auto lattice = [&](std::int64_t x, std::int64_t y, std::int64_t z) {
    const auto h = mix64(seed ^ mix64(static_cast<std::uint64_t>(x) * 0x8da6b343u ^
                                      static_cast<std::uint64_t>(y) * 0xd8163841u ^
                                      static_cast<std::uint64_t>(z) * 0xcb1ab31fu));
    return static_cast<float>(h >> 40) * (2.0f / 16777216.0f) - 1.0f;
  };
  const float sx = smooth01(t.x()), sy = smooth01(t.y()), sz = smooth01(t.z());
  float v = 0.0f;
  for (int dz = 0; dz <= 1; ++dz)
    for (int dy = 0; dy <= 1; ++dy)
      for (int dx = 0; dx <= 1; ++dx) {
        const float w = (dx ? sx : 1 - sx) * (dy ? sy : 1 - sy) * (dz ? sz : 1 - sz);
        v += w * lattice(ix + dx, iy + dy, iz + dz);
      }
  return v;
}

Eigen::Vector3f vertex(std::span<const float> mesh, std::uint32_t v) {
  return {mesh[3 * v], mesh[3 * v + 1], mesh[3 * v + 2]};
}

struct FaceFrame {
  Eigen::Vector3f centre;  // landmark centroid
  float brow_y, nose_y, chin_y, front_z, brow_z;
};

FaceFrame face_frame(const FaceModel& model, std::span<const float> mesh) {
  FaceFrame f{};
  Eigen::Vector3f c = Eigen::Vector3f::Zero();
  for (auto v : model.landmark_vertices) c += vertex(mesh, v);
  f.centre = c / 68.0f;
  f.brow_y = f.brow_z = 0.0f;
  for (int l = 17; l <= 26; ++l) {
    f.brow_y += vertex(mesh, model.landmark_vertices[l]).y() / 10.0f;
    f.brow_z += vertex(mesh, model.landmark_vertices[l]).z() / 10.0f;
  }
  f.nose_y = vertex(mesh, model.landmark_vertices[33]).y();
  f.chin_y = vertex(mesh, model.landmark_vertices[8]).y();
  f.front_z = std::numeric_limits<float>::infinity();
  for (int l : {17, 26, 36, 45, 48, 54})
    f.front_z = std::min(f.front_z, vertex(mesh, model.landmark_vertices[l]).z());
  f.front_z -= 20.0f;
  return f;
}

}  // namespace

void adjust_identity(const SyntheticWorld& world, std::vector<float>& c) {
  for (auto& x : c) x *= static_cast<float>(world.identity_scale);
  const int n = std::min<int>(world.identity_extreme_modes, static_cast<int>(c.size()));
  for (int k = 0; k < n; ++k) {
    const float sign = c[k] < 0.0f ? -1.0f : 1.0f;
    c[k] = sign * std::max(std::abs(c[k]), 3.5f);
  }
}

void displace_identity(const SyntheticWorld& world, const FaceModel& model, std::span<float> mesh) {
  if (world.displacement_mm <= 0.0 && world.asymmetry_mm == 0.0) return;
  const int V = model.vertex_count;
  const FaceFrame ff = face_frame(model, mesh);
  std::vector<Eigen::Vector3f> normals(static_cast<std::size_t>(V), Eigen::Vector3f::Zero());
  for (std::size_t t = 0; t + 2 < model.triangles.size(); t += 3) {
    const auto a = model.triangles[t], b = model.triangles[t + 1], c = model.triangles[t + 2];
    const Eigen::Vector3f n =
        (vertex(mesh, b) - vertex(mesh, a)).cross(vertex(mesh, c) - vertex(mesh, a));
    normals[a] += n;
    normals[b] += n;
    normals[c] += n;
  }
  std::vector<float> field(static_cast<std::size_t>(V), 0.0f);
  if (world.displacement_mm > 0.0) {
    // Bumps centred on random front-of-face vertices, 12-40 mm wide, either sign: smooth, and
    // asymmetric because left and right are drawn independently.
    std::vector<std::uint32_t> front;
    for (int v = 0; v < model.face_vertex_count; ++v)
      if (mesh[3 * v + 2] > ff.front_z) front.push_back(static_cast<std::uint32_t>(v));
    constexpr int kBumps = 12;
    for (int k = 0; k < kBumps && !front.empty(); ++k) {
      const auto pick = static_cast<std::size_t>(uniform(world.seed, kStreamBumps, 4 * k) *
                                                 static_cast<double>(front.size()));
      const Eigen::Vector3f c = vertex(mesh, front[std::min(pick, front.size() - 1)]);
      const float r =
          12.0f + 28.0f * static_cast<float>(uniform(world.seed, kStreamBumps, 4 * k + 1));
      const float a =
          (uniform(world.seed, kStreamBumps, 4 * k + 2) < 0.5 ? -1.0f : 1.0f) *
          (0.5f + 0.5f * static_cast<float>(uniform(world.seed, kStreamBumps, 4 * k + 3)));
      for (int v = 0; v < V; ++v) {
        const float d2 = (vertex(mesh, static_cast<std::uint32_t>(v)) - c).squaredNorm();
        if (d2 < 9.0f * r * r) field[v] += a * std::exp(-d2 / (2.0f * r * r));
      }
    }
    float peak = 0.0f;
    for (int v = 0; v < model.face_vertex_count; ++v) peak = std::max(peak, std::abs(field[v]));
    const float scale = peak > 0.0f ? static_cast<float>(world.displacement_mm) / peak : 0.0f;
    for (auto& f : field) f *= scale;
  }
  // The jaw off to one side: 0 above the nose base, asymmetry_mm at and below the chin.
  const float side = uniform(world.seed, kStreamAsym, 0) < 0.5 ? -1.0f : 1.0f;
  for (int v = 0; v < V; ++v) {
    const Eigen::Vector3f n = normals[v].normalized();
    Eigen::Vector3f d = field[v] * n;
    const float w = smooth01((ff.nose_y - mesh[3 * v + 1]) / std::max(1.0f, ff.nose_y - ff.chin_y));
    d.x() += side * static_cast<float>(world.asymmetry_mm) * w;
    for (int a = 0; a < 3; ++a) mesh[3 * v + a] += d[a];
  }
}

Eigen::Vector3f skin_albedo(double tone) {
  static constexpr std::array<std::array<float, 3>, 4> kTones = {
      {{242, 208, 190}, {215, 165, 135}, {160, 110, 80}, {92, 60, 44}}};
  const double t = std::clamp(tone, 0.0, 1.0) * 3.0;
  const int i = std::min(2, static_cast<int>(t));
  const float f = static_cast<float>(t - i);
  Eigen::Vector3f out;
  for (int a = 0; a < 3; ++a) out[a] = ((1 - f) * kTones[i][a] + f * kTones[i + 1][a]) / 255.0f;
  return out;
}

WorldRegions paint_regions(const SyntheticWorld& world, const FaceModel& model,
                           std::span<const float> mesh) {
  const int V = model.vertex_count;
  WorldRegions r;
  r.hair.assign(static_cast<std::size_t>(V), 0.0f);
  r.beard.assign(static_cast<std::size_t>(V), 0.0f);
  if (!world.hair && !world.beard) return r;
  const FaceFrame ff = face_frame(model, mesh);
  const float forehead = 35.0f + 20.0f * static_cast<float>(uniform(world.seed, kStreamHair, 0));
  auto lm = [&](int l) { return vertex(mesh, model.landmark_vertices[l]); };
  const float corner =
      0.5f * (std::abs(lm(48).x() - ff.centre.x()) + std::abs(lm(54).x() - ff.centre.x()));
  const float corner_y = 0.5f * (lm(48).y() + lm(54).y());
  const float jaw =
      0.5f * (std::abs(lm(1).x() - ff.centre.x()) + std::abs(lm(15).x() - ff.centre.x()));
  const float jaw_y = 0.5f * (lm(1).y() + lm(15).y());
  const float lip_y = lm(57).y();
  for (int v = 0; v < V; ++v) {
    const Eigen::Vector3f p = vertex(mesh, static_cast<std::uint32_t>(v));
    const float ax = std::abs(p.x() - ff.centre.x());
    if (world.hair) {
      // Hairline: forehead-high at the front, dropping over the temples and to the nape.
      const float back = smooth01((ff.brow_z - p.z() - 30.0f) / 60.0f);
      const float sides = smooth01((ax - 45.0f) / 25.0f);
      const float line = ff.brow_y + forehead - 30.0f * sides - 55.0f * back +
                         4.0f * value_noise(world.seed ^ kStreamHair, p / 10.0f);
      r.hair[v] = smooth01((p.y() - line) / 4.0f);
    }
    if (world.beard && p.z() > ff.brow_z - 90.0f) {
      // Below the line from the mouth corners to the upper jaw, down to under the chin.
      float line = lip_y - 2.0f;
      if (ax > corner)
        line = corner_y + (jaw_y - corner_y) *
                              std::clamp((ax - corner) / std::max(1.0f, jaw - corner), 0.0f, 1.0f);
      line += 3.0f * value_noise(world.seed ^ kStreamHair ^ 0x55, p / 8.0f);
      r.beard[v] = smooth01((line - p.y()) / 3.0f) *
                   smooth01((p.y() - (ff.chin_y - 30.0f)) / 10.0f) * (1.0f - r.hair[v]);
    }
  }
  return r;
}

WorldLight world_light(const SyntheticWorld& world, std::uint64_t frame) {
  WorldLight l;
  if (!world.light_vary) return l;
  auto u = [&](int k) { return uniform(world.seed, kStreamLight, static_cast<std::uint64_t>(k)); };
  const double t = static_cast<double>(frame) / 30.0, two_pi = 2.0 * std::numbers::pi;
  // Per take: a key light anywhere from the subject's left to right, from level to 45 deg
  // above, weak to full; over the take it drifts 12 deg and +-12 % (clouds, a door, a screen).
  const double azimuth = (-55.0 + 110.0 * u(0) + 12.0 * std::sin(two_pi * t / 7.0 + 6.28 * u(1))) *
                         std::numbers::pi / 180.0;
  const double elevation = (5.0 + 40.0 * u(2)) * std::numbers::pi / 180.0;
  const double intensity =
      (0.55 + 0.45 * u(3)) * (1.0 + 0.12 * std::sin(two_pi * t / 5.0 + 6.28 * u(4)));
  l.to_light = Eigen::Vector3f(static_cast<float>(std::sin(azimuth) * std::cos(elevation)),
                               static_cast<float>(-std::sin(elevation)),
                               static_cast<float>(-std::cos(azimuth) * std::cos(elevation)))
                   .normalized();
  l.ambient = static_cast<float>(0.12 + 0.23 * u(5));
  l.diffuse = static_cast<float>(intensity);
  const float warm = static_cast<float>(u(6) * 2.0 - 1.0);
  l.tint = Eigen::Vector3f(1.0f + 0.06f * warm, 1.0f, 1.0f - 0.06f * warm);
  return l;
}

Eigen::Vector3f textured_albedo(const SyntheticWorld& world, const Eigen::Vector3f& albedo,
                                const Eigen::Vector3f& p, float hair, float beard, float brow) {
  const std::uint64_t s = world.seed ^ kStreamTexture;
  // Skin: blotches (14 mm), mottling (5 mm), redness patches, pores and freckles (1.6 mm).
  float f = 1.0f + 0.07f * value_noise(s, p / 14.0f) + 0.04f * value_noise(s + 1, p / 5.0f);
  if (value_noise(s + 2, p / 1.6f) > 0.55f) f *= 0.9f;
  Eigen::Vector3f out = albedo * f;
  out.x() += 0.03f * value_noise(s + 3, p / 9.0f);
  // Brow hairs: strokes along the brow (stretched across x).
  if (brow > 0.0f) {
    const Eigen::Vector3f q(p.x() / 5.0f, p.y() / 0.6f, p.z() / 5.0f);
    out *= 1.0f + 0.45f * brow * value_noise(s + 4, q);
  }
  // Hair strands run down the head (stretched along y); stubble is fine speckle.
  if (hair > 0.0f) {
    const Eigen::Vector3f q(p.x() / 0.6f, p.y() / 7.0f, p.z() / 0.6f);
    out *= 1.0f + hair * (0.4f * value_noise(s + 5, q) + 0.15f * value_noise(s + 6, p / 3.0f));
  }
  if (beard > 0.0f) out *= 1.0f + 0.5f * beard * value_noise(s + 7, p / 0.7f);
  return out.cwiseMax(0.0f);
}

// ---------------------------------------------------------------------------------------------
// Props

WorldProps::WorldProps(const SyntheticWorld& world, int frame_count, const Eigen::Vector3f& head,
                       const Eigen::Vector3f& skin)
    : world_(world), frame_count_(frame_count), head0_(head) {
  auto u = [&](int k) {
    return static_cast<float>(uniform(world.seed, kStreamProps, static_cast<std::uint64_t>(k)));
  };
  if (world.torso) {
    static constexpr std::array<std::array<float, 3>, 5> kShirts = {
        {{40, 60, 110}, {150, 40, 45}, {60, 60, 62}, {210, 205, 195}, {70, 110, 70}}};
    const auto& c = kShirts[static_cast<std::size_t>(u(0) * 5.0f) % 5];
    add_torso(head, Eigen::Vector3f(c[0], c[1], c[2]) / 255.0f);
  }
  if (world.desk) add_desk(head);
  if (world.side_hand) {
    // A forearm rising from the bottom of the frame and a hand resting beside the face,
    // 130-140 mm nearer than it.
    const Eigen::Vector3f axis = Eigen::Vector3f(-0.15f, -1.0f, 0.1f).normalized();
    Eigen::Matrix3f arm;
    arm.col(1) = 150.0f * axis;
    arm.col(0) = 38.0f * Eigen::Vector3f::UnitX().cross(axis).cross(axis).normalized();
    arm.col(2) = 35.0f * axis.cross(arm.col(0).normalized());
    add_ellipsoid(head + Eigen::Vector3f(165, 230, -130), arm, skin, true, false);
    add_ellipsoid(head + Eigen::Vector3f(135, 60, -140), Eigen::Vector3f(42, 85, 25).asDiagonal(),
                  skin, true, false);
  }
  if (world.hand_pass) {
    Eigen::Matrix3f palm = Eigen::Vector3f(45, 85, 20).asDiagonal();
    add_ellipsoid(Eigen::Vector3f::Zero(), palm, skin, true, true);
    add_ellipsoid(Eigen::Vector3f(0, 190, 20), Eigen::Vector3f(33, 120, 30).asDiagonal(), skin,
                  true, true);
    if (world_.hand_pass_start < 0)
      world_.hand_pass_start = std::max(0, frame_count / 2 - world_.hand_pass_frames / 2);
  }
}

void WorldProps::add_facing(const Eigen::Vector3f& a, const Eigen::Vector3f& b,
                            const Eigen::Vector3f& c, const Eigen::Vector3f& outward) {
  // Front faces are counter-clockwise seen from outside: (b - a) x (c - a) along `outward`.
  const auto base = static_cast<std::uint32_t>(rest_.size());
  rest_.insert(rest_.end(), {a, b, c});
  if ((b - a).cross(c - a).dot(outward) >= 0.0f)
    triangles_.insert(triangles_.end(), {base, base + 1, base + 2});
  else
    triangles_.insert(triangles_.end(), {base, base + 2, base + 1});
}

void WorldProps::add_ellipsoid(const Eigen::Vector3f& centre, const Eigen::Matrix3f& axes,
                               const Eigen::Vector3f& albedo, bool hand, bool moving) {
  Part part;
  part.first_vertex = static_cast<std::uint32_t>(rest_.size());
  part.first_triangle = static_cast<std::uint32_t>(triangles_.size() / 3);
  part.albedo = albedo;
  part.hand = hand;
  part.moving = moving;
  constexpr int kLat = 10, kLon = 18;
  auto point = [&](int i, int j) {
    const double th = std::numbers::pi * i / kLat - std::numbers::pi / 2;
    const double ph = 2.0 * std::numbers::pi * j / kLon;
    const Eigen::Vector3f unit(static_cast<float>(std::cos(th) * std::cos(ph)),
                               static_cast<float>(std::sin(th)),
                               static_cast<float>(std::cos(th) * std::sin(ph)));
    return Eigen::Vector3f(centre + axes * unit);
  };
  for (int i = 0; i < kLat; ++i)
    for (int j = 0; j < kLon; ++j) {
      const Eigen::Vector3f a = point(i, j), b = point(i, j + 1), c = point(i + 1, j + 1),
                            d = point(i + 1, j);
      const Eigen::Vector3f mid = 0.25f * (a + b + c + d) - centre;
      if (i > 0) add_facing(a, b, c, mid);
      if (i + 1 < kLat) add_facing(a, c, d, mid);
    }
  part.vertex_count = static_cast<std::uint32_t>(rest_.size()) - part.first_vertex;
  part.triangle_count = static_cast<std::uint32_t>(triangles_.size() / 3) - part.first_triangle;
  parts_.push_back(part);
}

void WorldProps::add_torso(const Eigen::Vector3f& h, const Eigen::Vector3f& albedo) {
  Part part;
  part.first_vertex = static_cast<std::uint32_t>(rest_.size());
  part.first_triangle = static_cast<std::uint32_t>(triangles_.size() / 3);
  part.albedo = albedo;
  // Shoulders 150 mm below the face centre, 40 mm behind it; the chest leans towards the
  // camera and is 120 mm nearer than the face 420 mm below it (the bottom of the frame).
  constexpr float kHalfWidth = 210.0f;
  constexpr int kCols = 20, kRows = 12;
  auto point = [&](int i, int j) {
    const float t = static_cast<float>(i) / kRows;
    const float x = kHalfWidth * (2.0f * j / kCols - 1.0f), s = x / kHalfWidth;
    const float y = h.y() + 150.0f + 270.0f * t + 45.0f * s * s * (1.0f - t);
    const float z = h.z() + 40.0f - 160.0f * t + 110.0f * (1.0f - std::sqrt(1.0f - 0.98f * s * s));
    return Eigen::Vector3f(h.x() + x, y, z);
  };
  for (int i = 0; i < kRows; ++i)
    for (int j = 0; j < kCols; ++j) {
      const Eigen::Vector3f a = point(i, j), b = point(i, j + 1), c = point(i + 1, j + 1),
                            d = point(i + 1, j);
      add_facing(a, b, c, -Eigen::Vector3f::UnitZ());
      add_facing(a, c, d, -Eigen::Vector3f::UnitZ());
    }
  part.vertex_count = static_cast<std::uint32_t>(rest_.size()) - part.first_vertex;
  part.triangle_count = static_cast<std::uint32_t>(triangles_.size() / 3) - part.first_triangle;
  parts_.push_back(part);
}

void WorldProps::add_desk(const Eigen::Vector3f& h) {
  Part part;
  part.first_vertex = static_cast<std::uint32_t>(rest_.size());
  part.first_triangle = static_cast<std::uint32_t>(triangles_.size() / 3);
  part.albedo = Eigen::Vector3f(150, 110, 75) / 255.0f;
  // A desk top 215 mm below the face centre, its front edge 170 mm nearer than the face (not
  // nearer than 530 mm, inside the Kinect's range); seen at a grazing angle from face height.
  const float y = h.y() + 215.0f, near = std::max(530.0f, h.z() - 170.0f), far = h.z() + 500.0f;
  const float x0 = h.x() - 700.0f, x1 = h.x() + 700.0f;
  constexpr int kStrips = 8;  // the top in strips, so no triangle spans the whole depth range
  for (int k = 0; k < kStrips; ++k) {
    const float za = near + (far - near) * k / kStrips,
                zb = near + (far - near) * (k + 1) / kStrips;
    add_facing({x0, y, za}, {x1, y, za}, {x1, y, zb}, -Eigen::Vector3f::UnitY());
    add_facing({x0, y, za}, {x1, y, zb}, {x0, y, zb}, -Eigen::Vector3f::UnitY());
  }
  add_facing({x0, y, near}, {x1, y, near}, {x1, y + 60.0f, near}, -Eigen::Vector3f::UnitZ());
  add_facing({x0, y, near}, {x1, y + 60.0f, near}, {x0, y + 60.0f, near},
             -Eigen::Vector3f::UnitZ());
  part.vertex_count = static_cast<std::uint32_t>(rest_.size()) - part.first_vertex;
  part.triangle_count = static_cast<std::uint32_t>(triangles_.size() / 3) - part.first_triangle;
  parts_.push_back(part);
}

void WorldProps::append(std::vector<Eigen::Vector3f>& vertices,
                        std::vector<std::uint32_t>& triangles) {
  first_vertex_ = static_cast<std::uint32_t>(vertices.size());
  first_triangle_ = static_cast<std::uint32_t>(triangles.size() / 3);
  vertices.insert(vertices.end(), rest_.begin(), rest_.end());
  for (auto i : triangles_) triangles.push_back(first_vertex_ + i);
}

bool WorldProps::hand_passing(std::uint64_t frame) const {
  if (!world_.hand_pass) return false;
  const auto start = static_cast<std::uint64_t>(world_.hand_pass_start);
  return frame >= start && frame < start + static_cast<std::uint64_t>(world_.hand_pass_frames);
}

void WorldProps::pose(std::uint64_t frame, const Eigen::Vector3f& head,
                      std::span<Eigen::Vector3f> vertices) const {
  const bool on = hand_passing(frame);
  // The palm sweeps from the subject's right to left, 130 mm in front of the face, at nose
  // height; behind the camera (not drawn) outside the pass.
  const float s =
      on ? static_cast<float>(frame - static_cast<std::uint64_t>(world_.hand_pass_start)) /
               static_cast<float>(std::max(1, world_.hand_pass_frames - 1))
         : 0.0f;
  const Eigen::Vector3f centre =
      on ? Eigen::Vector3f(head + Eigen::Vector3f(-200.0f + 400.0f * s, 15.0f, -130.0f))
         : Eigen::Vector3f(0.0f, 0.0f, -1000.0f);
  for (const auto& part : parts_) {
    if (!part.moving) continue;
    for (std::uint32_t k = 0; k < part.vertex_count; ++k)
      vertices[first_vertex_ + part.first_vertex + k] = centre + rest_[part.first_vertex + k];
  }
}

Eigen::Vector3f WorldProps::albedo(std::uint32_t t) const {
  for (const auto& part : parts_)
    if (t >= first_triangle_ + part.first_triangle &&
        t < first_triangle_ + part.first_triangle + part.triangle_count)
      return part.albedo;
  return Eigen::Vector3f::Constant(0.5f);
}

bool WorldProps::is_hand(std::uint32_t t) const {
  for (const auto& part : parts_)
    if (t >= first_triangle_ + part.first_triangle &&
        t < first_triangle_ + part.first_triangle + part.triangle_count)
      return part.hand;
  return false;
}

// ---------------------------------------------------------------------------------------------
// Depth of hair and beard, and occlusion truth

void degrade_material_depth(const KinectSensorModel& sensor, std::span<const MaterialPixel> regions,
                            std::uint64_t noise_seed, SensorFrame& frame) {
  const int w = frame.raw.width, h = frame.raw.height;
  const auto& registration = sensor.registration();
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * w + x;
      const MaterialPixel m = regions[i];
      if (m.hair < 0.05f && m.beard < 0.05f) continue;
      if (frame.invalid.pixels[i] != 0 || frame.raw.pixels[i] == kInvalidDisparity) continue;
      // Clustered dropouts (3x3-pixel cells) and isolated ones.
      const std::size_t cell =
          static_cast<std::size_t>(y / 3) * static_cast<std::size_t>(w) + x / 3;
      const double cell_u = uniform(noise_seed, kStreamMaterial, 2 * cell);
      const double pixel_u = uniform(noise_seed, kStreamMaterial + 1, i);
      if (cell_u < 0.35 * m.hair + 0.15 * m.beard || pixel_u < 0.12 * m.hair + 0.06 * m.beard) {
        frame.raw.pixels[i] = kInvalidDisparity;
        frame.depth_mm.pixels[i] = 0;
        frame.invalid.pixels[i] = kSensorMaterial;
        continue;
      }
      // The hair surface sits in front of the scalp (8 mm; stubble 3 mm) and scatters.
      const double z = frame.noiseless_depth_mm.pixels[i];
      const double r0 = sensor.fractional_raw(z),
                   r1 = sensor.fractional_raw(z - 8.0 * m.hair - 3.0 * m.beard);
      if (r0 < 0.0 || r1 < 0.0) continue;
      const double sigma = 3.0 * m.hair + 1.8 * m.beard;
      const double r =
          frame.raw.pixels[i] + (r1 - r0) + sigma * gaussian(noise_seed, kStreamMaterial + 2, i);
      const long rounded = static_cast<long>(std::floor(r + 0.5));
      const std::uint16_t mm = rounded > 0 && rounded < kInvalidDisparity
                                   ? registration.raw_to_mm(static_cast<std::uint16_t>(rounded))
                                   : 0;
      if (mm == 0) {
        frame.raw.pixels[i] = kInvalidDisparity;
        frame.depth_mm.pixels[i] = 0;
        frame.invalid.pixels[i] = kSensorMaterial;
      } else {
        frame.raw.pixels[i] = static_cast<std::uint16_t>(rounded);
        frame.depth_mm.pixels[i] = mm;
      }
    }
}

double face_hidden_fraction(const RasterBuffers& raster, const WorldProps& props,
                            std::span<const Eigen::Vector2d> px) {
  if (px.size() < 27) return 0.0;
  std::vector<Eigen::Vector2d> poly;
  for (int l = 0; l <= 16; ++l) poly.push_back(px[l]);
  for (int l = 26; l >= 17; --l) poly.push_back(px[l]);
  double x0 = 1e9, x1 = -1e9, y0 = 1e9, y1 = -1e9;
  for (const auto& p : poly) {
    if (!p.allFinite()) return 0.0;
    x0 = std::min(x0, p.x()), x1 = std::max(x1, p.x()), y0 = std::min(y0, p.y()),
    y1 = std::max(y1, p.y());
  }
  long inside = 0, hidden = 0;
  for (int y = std::max(0, static_cast<int>(y0));
       y <= std::min(raster.height - 1, static_cast<int>(y1) + 1); ++y)
    for (int x = std::max(0, static_cast<int>(x0));
         x <= std::min(raster.width - 1, static_cast<int>(x1) + 1); ++x) {
      bool in = false;
      for (std::size_t i = 0, j = poly.size() - 1; i < poly.size(); j = i++) {
        if ((poly[i].y() > y) != (poly[j].y() > y) &&
            x < (poly[j].x() - poly[i].x()) * (y - poly[i].y()) / (poly[j].y() - poly[i].y()) +
                    poly[i].x())
          in = !in;
      }
      if (!in) continue;
      ++inside;
      const std::int32_t t = raster.triangle[raster.index(x, y)];
      if (t != kNoTriangle && props.is_hand(static_cast<std::uint32_t>(t))) ++hidden;
    }
  return inside > 0 ? static_cast<double>(hidden) / static_cast<double>(inside) : 0.0;
}

}  // namespace fb
