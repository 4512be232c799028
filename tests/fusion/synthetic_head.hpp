// A tiny analytic test scene for the fusion tests: a head made of ellipsoids (skull, nose,
// brow, cheeks, chin, ears) ray-cast exactly into a Kinect-sized depth image, with a Kinect v1
// style noise model and known camera_from_model poses. Independent of the synthetic camera
// backend so the fusion module can be tested on its own.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include <Eigen/Geometry>

#include "algo/core/camera_model.hpp"
#include "algo/core/image.hpp"

namespace fb::test {

struct Ellipsoid {
  Eigen::Vector3d centre;
  Eigen::Vector3d axes;
};

inline std::vector<Ellipsoid> head_ellipsoids() {
  // Model frame: mm, origin at the head centre, the face looks towards -z (the camera).
  return {
      {{0, 0, 0}, {75, 100, 90}},     {{0, 8, -88}, {11, 24, 20}},   {{0, -38, -76}, {48, 11, 12}},
      {{-36, 22, -68}, {24, 18, 18}}, {{36, 22, -68}, {24, 18, 18}}, {{0, 72, -58}, {26, 20, 22}},
      {{-76, 0, 0}, {9, 26, 16}},     {{76, 0, 0}, {9, 26, 16}},     {{0, 45, -80}, {22, 7, 8}}};
}

inline PinholeIntrinsics kinect_intrinsics() {
  PinholeIntrinsics k;
  k.width = 640;
  k.height = 480;
  k.fx = k.fy = 580.0;
  k.cx = 319.5;
  k.cy = 239.5;
  return k;
}

// Approximate signed distance (mm) from a model-frame point to the head surface.
inline double head_distance(const Eigen::Vector3d& p) {
  double best = 1e9;
  for (const auto& e : head_ellipsoids()) {
    const double r = ((p - e.centre).cwiseQuotient(e.axes)).norm();
    // Scaled radial distance: exact for spheres, close for these mild ellipsoids near the
    // surface.
    const double d = (r - 1.0) * ((p - e.centre).norm() / std::max(r, 1e-9));
    best = std::min(best, d);
  }
  return best;
}

// Head turn: +/-30 deg yaw and +/-15 deg pitch over `frames`, head centre at 700 mm.
inline RigidPose head_turn_pose(int frame, int frames, Eigen::Vector3d offset = {0, 0, 0}) {
  const double s = 2.0 * M_PI * frame / frames;
  const double yaw = 30.0 * M_PI / 180.0 * std::sin(s);
  const double pitch = 15.0 * M_PI / 180.0 * std::sin(2.0 * s);
  RigidPose p;
  p.rotation = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitY()) *
               Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitX());
  p.translation = Eigen::Vector3d(0, 0, 700) + offset;
  return p;
}

// Exact depth (mm, 0 = miss) of the scene seen with camera_from_model.
inline void render_head(const PinholeIntrinsics& k, const RigidPose& camera_from_model,
                        Image<float>& depth) {
  depth.resize(k.width, k.height);
  const auto parts = head_ellipsoids();
  const RigidPose model_from_camera = camera_from_model.inverse();
  const Eigen::Matrix3d r = model_from_camera.rotation.toRotationMatrix();
  const Eigen::Vector3d o = model_from_camera.translation;  // camera centre in the model
  std::fill(depth.pixels.begin(), depth.pixels.end(), 0.0f);
  // Only pixels inside the projection of a sphere bounding the head can hit it.
  const Eigen::Vector3d c = camera_from_model.translation;
  const double radius = 120.0;
  if (c.z() <= radius) return;
  const double su = k.fx * radius / (c.z() - radius), sv = k.fy * radius / (c.z() - radius);
  const int u0 = std::max(0, static_cast<int>(k.fx * c.x() / c.z() + k.cx - su));
  const int u1 = std::min(k.width - 1, static_cast<int>(k.fx * c.x() / c.z() + k.cx + su));
  const int v0 = std::max(0, static_cast<int>(k.fy * c.y() / c.z() + k.cy - sv));
  const int v1 = std::min(k.height - 1, static_cast<int>(k.fy * c.y() / c.z() + k.cy + sv));
  for (int v = v0; v <= v1; ++v) {
    for (int u = u0; u <= u1; ++u) {
      // Ray x(t) = o + t d with the camera depth as t (d has camera z = 1).
      const Eigen::Vector3d d = r * Eigen::Vector3d((u - k.cx) / k.fx, (v - k.cy) / k.fy, 1.0);
      double best = 0.0;
      for (const auto& e : parts) {
        const Eigen::Vector3d oc = (o - e.centre).cwiseQuotient(e.axes);
        const Eigen::Vector3d dc = d.cwiseQuotient(e.axes);
        const double a = dc.squaredNorm(), b = 2.0 * oc.dot(dc), c = oc.squaredNorm() - 1.0;
        const double disc = b * b - 4 * a * c;
        if (disc < 0) continue;
        const double t = (-b - std::sqrt(disc)) / (2 * a);
        if (t > 0 && (best == 0.0 || t < best)) best = t;
      }
      depth.at(u, v) = static_cast<float>(best);
    }
  }
}

// Kinect v1 style measurement: sigma(z) = 1.2 mm + 1.9e-3 (z - 400 mm)^2 / 1000 mm, rounded to
// whole millimetres, with a few dropped pixels.
inline void kinect_noise(const Image<float>& truth, std::mt19937& rng, DepthImage& out,
                         double dropout = 0.02) {
  out.resize(truth.width, truth.height);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  for (std::size_t i = 0; i < truth.pixels.size(); ++i) {
    const double z = truth.pixels[i];
    if (z <= 0.0 || uni(rng) < dropout) {
      out.pixels[i] = 0;
      continue;
    }
    const double zm = z / 1000.0;
    const double sigma = 1.2 + 1.9 * (zm - 0.4) * (zm - 0.4);
    out.pixels[i] = static_cast<std::uint16_t>(std::lround(z + sigma * gauss(rng)));
  }
}

}  // namespace fb::test
