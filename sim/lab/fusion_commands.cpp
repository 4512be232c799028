// facebooth-lab eval fusion | bench fusion: the commands (fusion_eval.cpp, fusion_bench.cpp).
#include "sim/lab/fusion_lab.hpp"
#include "sim/lab/lab_commands.hpp"

namespace fb::cli {

#ifndef FB_REAL_DUMP_DEFAULT
#define FB_REAL_DUMP_DEFAULT "../shared/kinect/openiss-desk/test-recording-first90.tar.xz"
#endif

std::vector<Command> fusion_commands() {
  std::vector<OptionSpec> eval_options = {
      {"seeds", "N", "synthetic head-turn sequences (seeds first-seed..first-seed+N-1)", "5"},
      {"first-seed", "N", "first synthetic seed", "0"},
      {"frames", "N", "frames per sequence", "90"},
      {"scenario", "NAME",
       "realistic (a baseline, every part alone, then all: JSON scenarios.<part>; no real "
       "dump) or one part: identity|texture|hair|clutter|noise|unit (world_presets.hpp)",
       ""},
      {"synthetic", "URI", "base synthetic URI (seed and frames are appended)",
       "synthetic:motion=headturn"},
      {"frontal-frame", "N", "frame whose fused depth is scored", "0"},
      {"png", "PATH", "error map of the first seed (raw vs fused, mm colour scale)",
       "fusion_error.png"},
      {"error-scale-mm", "MM", "top of the error map's colour scale", "2"},
      {"mesh", "PATH", "write the first seed's fused mesh as PLY (empty: none)", ""},
      {"real", "PATH", "real fakenect dump (directory or .tar.xz), or off", FB_REAL_DUMP_DEFAULT},
      {"real-box", "detect|kiosk|X,Y,W,H", "face box for the real dump (as --box)", "detect"},
      {"real-mesh", "PATH", "PLY mesh written from the real dump", "fusion_real_mesh.ply"},
      {"verbose", "", "per-frame tracking state and stage times on stderr", ""},
      {"truth-poses", "", "diagnosis: fuse at the ground-truth poses instead of tracking", ""},
      {"json", "", "print JSON (the only output format; accepted for symmetry)", ""},
  };
  std::vector<OptionSpec> bench_options = {
      {"frames", "N", "frames of the synthetic head turn", "90"},
      {"seed", "N", "synthetic seed", "0"},
      {"camera", "URI", "time these frames instead (any camera URI)", ""},
      {"repeats", "N",
       "runs per configuration; ms_per_frame is the fastest, ms_per_frame_median and "
       "ms_per_frame_runs give the spread",
       "3"},
      {"verbose", "", "per-frame figures on stderr", ""},
      {"open3d", "PATH",
       "the facebooth-bench-open3d executable, or off (default: found next "
       "to facebooth or in the build tree)",
       ""},
      {"json", "", "print JSON (the only output format; accepted for symmetry)", ""},
  };
  for (const auto& o : fusion_lab::fusion_option_specs()) {
    eval_options.push_back(o);
    bench_options.push_back(o);
  }
  return {
      {{"eval fusion",
        "score the face-box KinectFusion against synthetic ground truth and on the real dump",
        "Prints one JSON object on stdout: pose_error_mm_max and pose_error_deg_max (the head's "
        "pose relative to the first frame; mm = displacement at the face, the landmark "
        "centroid), camera_centre_error_mm_max (the same error at the camera centre, ~0.7 m "
        "away), fused_depth_mae_mm beside raw_depth_mae_mm (frontal frame, landmark-hull face "
        "region), fill_fraction, per-seed figures, and the real dump's run (lost frames, "
        "mesh). Writes the error map PNG and PLY meshes.",
        eval_options},
       fusion_lab::run_eval_fusion},
      {{"bench fusion",
        "per-frame fusion time by stage (1 and 2 threads) beside Open3D on the same frames",
        "Prints one JSON object on stdout: ms_per_frame (ICP + integrate + ray-cast, one thread, "
        "CPU time), ms_per_frame_2threads (wall), open3d_ms_per_frame, speedup_vs_open3d, "
        "peak_rss_mb and the per-stage split; on a CPU with AVX2 also ms_per_frame_4lanes (the "
        "voxel update at the 4-lane width of the device's NEON).",
        bench_options},
       fusion_lab::run_bench_fusion},
  };
}

}  // namespace fb::cli
