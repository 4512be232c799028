// facebooth-bench-open3d FRAMES_FILE: Open3D 0.16's CPU TSDF pipeline on the same frames and face
// box as `facebooth-lab bench fusion`, timed per stage. One JSON object on stdout.
//
// Per frame (as Open3D's own t::pipelines::slam::Model does it): point-to-plane odometry of the
// frame against the model ray-cast at the previous pose (3 scales, 10/5/3 iterations),
// then VoxelBlockGrid::Integrate of the frame, then VoxelBlockGrid::RayCast of depth + normals at
// the new pose. Same voxel size (volume size / resolution), truncation and depth range, and
// depth outside the face box set to 0, so both pipelines see the same pixels.
//
// The frames file (written by facebooth): one text line
//   FBDEPTH1 width height frames fx fy cx cy box_x box_y box_w box_h depth_min_mm depth_max_mm
//   voxel_mm truncation_mm
// followed by frames * width * height little-endian uint16 depths in mm.
#include <sys/resource.h>
#include <time.h>

#include <open3d/Open3D.h>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

namespace {

namespace o3c = open3d::core;
namespace o3g = open3d::t::geometry;
namespace odo = open3d::t::pipelines::odometry;

double process_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

struct Lap {
  std::chrono::steady_clock::time_point wall = std::chrono::steady_clock::now();
  double cpu = process_cpu_ms();
  void take(double& wall_acc, double& cpu_acc) {
    const auto now = std::chrono::steady_clock::now();
    const double c = process_cpu_ms();
    wall_acc += std::chrono::duration<double, std::milli>(now - wall).count();
    cpu_acc += c - cpu;
    wall = now;
    cpu = c;
  }
};

struct Header {
  int width = 0, height = 0, frames = 0;
  double fx = 0, fy = 0, cx = 0, cy = 0;
  int bx = 0, by = 0, bw = 0, bh = 0;
  double depth_min_mm = 0, depth_max_mm = 0, voxel_mm = 0, truncation_mm = 0;
};

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: facebooth-bench-open3d FRAMES_FILE  (written by `facebooth-lab bench "
                 "fusion`)\n";
    return 2;
  }
  std::ifstream in(argv[1], std::ios::binary);
  if (!in) {
    std::cerr << "facebooth-bench-open3d: cannot open " << argv[1] << "\n";
    return 1;
  }
  std::string line;
  std::getline(in, line);
  std::istringstream hs(line);
  std::string magic;
  Header h;
  hs >> magic >> h.width >> h.height >> h.frames >> h.fx >> h.fy >> h.cx >> h.cy >> h.bx >> h.by >>
      h.bw >> h.bh >> h.depth_min_mm >> h.depth_max_mm >> h.voxel_mm >> h.truncation_mm;
  if (magic != "FBDEPTH1" || !hs || h.width <= 0 || h.height <= 0 || h.frames <= 0) {
    std::cerr << "facebooth-bench-open3d: " << argv[1] << " is not a FBDEPTH1 frames file\n";
    return 1;
  }
  const std::size_t pixels = static_cast<std::size_t>(h.width) * h.height;
  std::vector<std::vector<std::uint16_t>> frames(h.frames, std::vector<std::uint16_t>(pixels));
  for (auto& f : frames) {
    in.read(reinterpret_cast<char*>(f.data()), static_cast<std::streamsize>(pixels * 2));
    if (!in) {
      std::cerr << "facebooth-bench-open3d: " << argv[1] << " is truncated\n";
      return 1;
    }
    // Same pixels as facebooth: the face box only, and the depth gate.
    for (int y = 0; y < h.height; ++y)
      for (int x = 0; x < h.width; ++x) {
        std::uint16_t& d = f[static_cast<std::size_t>(y) * h.width + x];
        const bool in_box = x >= h.bx && x < h.bx + h.bw && y >= h.by && y < h.by + h.bh;
        if (!in_box || d < h.depth_min_mm || d > h.depth_max_mm) d = 0;
      }
  }

  const o3c::Device cpu("CPU:0");
  const o3c::Tensor intrinsic =
      o3c::Tensor::Init<double>({{h.fx, 0, h.cx}, {0, h.fy, h.cy}, {0, 0, 1}});
  const float depth_scale = 1000.0f;  // mm -> m
  const float depth_max = static_cast<float>(h.depth_max_mm / 1000.0);
  const float depth_min = static_cast<float>(h.depth_min_mm / 1000.0);
  const float voxel = static_cast<float>(h.voxel_mm / 1000.0);
  const float trunc_multiplier = static_cast<float>(h.truncation_mm / h.voxel_mm);
  o3g::VoxelBlockGrid grid({"tsdf", "weight"}, {o3c::Float32, o3c::Float32}, {{1}, {1}}, voxel, 8,
                           20000, cpu);
  odo::OdometryLossParams loss;
  // Open3D's default loss parameters (outlier gate 7 cm, Huber 5 cm).

  // Frame-to-model point-to-plane odometry, coarse to fine, as RGBDOdometryMultiScale(...,
  // Method::PointToPlane) does it; its bilateral pre-filter is left out because Open3D 0.16
  // has no CPU Float32 FilterBilateral without IPP (which only makes Open3D's figure smaller).
  std::vector<o3c::Tensor> intrinsics_pyramid;
  for (int l = 0; l < 3; ++l) {
    const double s = 1.0 / (1 << l);
    intrinsics_pyramid.push_back(
        o3c::Tensor::Init<double>({{h.fx * s, 0, h.cx * s}, {0, h.fy * s, h.cy * s}, {0, 0, 1}}));
  }
  const int iterations[3] = {10, 5, 3};  // Open3D's default criteria, finest level first
  auto track = [&](const o3g::Image& depth_mm, const o3g::Image& model_mm) {
    std::vector<o3g::Image> src, tgt;
    src.push_back(depth_mm.ClipTransform(depth_scale, depth_min, depth_max, NAN));
    tgt.push_back(model_mm.ClipTransform(depth_scale, depth_min, depth_max, NAN));
    for (int l = 1; l < 3; ++l) {
      src.push_back(src.back().PyrDownDepth(0.05f, NAN));
      tgt.push_back(tgt.back().PyrDownDepth(0.05f, NAN));
    }
    o3c::Tensor t = o3c::Tensor::Eye(4, o3c::Float64, cpu);
    for (int l = 2; l >= 0; --l) {
      o3g::Image sv = src[l].CreateVertexMap(intrinsics_pyramid[l], NAN);
      o3g::Image tv = tgt[l].CreateVertexMap(intrinsics_pyramid[l], NAN);
      o3g::Image tn = tv.CreateNormalMap(NAN);
      for (int it = 0; it < iterations[l]; ++it) {
        const auto r = odo::ComputeOdometryResultPointToPlane(
            sv.AsTensor(), tv.AsTensor(), tn.AsTensor(), intrinsics_pyramid[l], t,
            loss.depth_outlier_trunc_, loss.depth_huber_delta_);
        t = r.transformation_.Matmul(t).Contiguous();
      }
    }
    return t;  // camera_prev_from_camera_now (source = this frame, target = the model view)
  };

  o3c::Tensor pose = o3c::Tensor::Eye(4, o3c::Float64, cpu);  // world_from_camera
  o3g::Image model_depth;
  double odo_ms = 0, int_ms = 0, ray_ms = 0, odo_wall = 0, int_wall = 0, ray_wall = 0;
  double first_ms = 0;
  int tracked = 0;
  nlohmann::json poses = nlohmann::json::array();
  for (int i = 0; i < h.frames; ++i) {
    const double frame_cpu0 = process_cpu_ms();
    o3g::Image depth(o3c::Tensor(frames[i], {h.height, h.width, 1}, o3c::UInt16, cpu));
    Lap lap;
    if (i > 0) {
      try {
        pose = pose.Matmul(track(depth, model_depth)).Contiguous();
        ++tracked;
      } catch (const std::exception& e) {
        std::cerr << "facebooth-bench-open3d: odometry failed on frame " << i << ": " << e.what()
                  << "\n";
        return 1;
      }
      double ow = 0, oc = 0;
      lap.take(ow, oc);
      if (i > 1) {
        odo_wall += ow;
        odo_ms += oc;
      }
    }
    const o3c::Tensor extrinsic = pose.Inverse().Contiguous();  // camera_from_world
    const o3c::Tensor blocks = grid.GetUniqueBlockCoordinates(
        depth, intrinsic, extrinsic, depth_scale, depth_max, trunc_multiplier);
    grid.Integrate(blocks, depth, intrinsic, extrinsic, depth_scale, depth_max, trunc_multiplier);
    double iw = 0, ic = 0;
    lap.take(iw, ic);
    const auto rendered =
        grid.RayCast(blocks, intrinsic, extrinsic, h.width, h.height, {"depth", "normal"},
                     depth_scale, depth_min, depth_max, 1.0f, trunc_multiplier);
    // Ray-cast depth is float in depth_scale units; the odometry reads it as the target.
    model_depth = o3g::Image(rendered.at("depth"));
    double rw = 0, rc = 0;
    lap.take(rw, rc);
    if (i > 1) {  // frames 0 and 1 include one-off setup, as for facebooth's figure
      int_wall += iw;
      int_ms += ic;
      ray_wall += rw;
      ray_ms += rc;
    } else {
      first_ms += process_cpu_ms() - frame_cpu0;
    }
    const o3c::Tensor p = pose.To(o3c::Float64).Contiguous();
    std::vector<double> flat(p.GetDataPtr<double>(), p.GetDataPtr<double>() + 16);
    poses.push_back(flat);
  }
  const int timed = std::max(1, h.frames - 2);
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  nlohmann::json out;
  out["open3d_version"] = OPEN3D_VERSION;
  out["frames"] = h.frames;
  out["timed_frames"] = timed;
  out["tracked_frames"] = tracked;
  out["odometry_ms"] = odo_ms / timed;
  out["integrate_ms"] = int_ms / timed;
  out["raycast_ms"] = ray_ms / timed;
  out["ms_per_frame"] = (odo_ms + int_ms + ray_ms) / timed;
  out["wall_ms_per_frame"] = (odo_wall + int_wall + ray_wall) / timed;
  out["voxel_mm"] = h.voxel_mm;
  out["truncation_mm"] = h.truncation_mm;
  out["block_resolution"] = 8;
  out["peak_rss_mb"] = static_cast<double>(usage.ru_maxrss) / 1024.0;
  out["poses_world_from_camera"] = poses;  // row-major 4x4, metres
  std::cout << out.dump() << std::endl;
  return 0;
}
