// facebooth-lab bench camera: frames per second of the synthetic and replay backends.
// One JSON object on stdout, human-readable progress on stderr (the contract every
// `bench`/`eval` command follows).
#include <chrono>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>

#include "algo/core/clock.hpp"
#include "drivers/camera/recorder/recorder.hpp"
#include "sim/lab/lab_commands.hpp"
#include "host/cli/frame_open.hpp"
#include "host/cli/scratch_directory.hpp"

namespace fb::cli {
namespace {

// Reads every frame of a camera (up to `max_frames`) and returns frames per second.
Result<double> measure_fps(const std::string& uri, long long max_frames, long long& frames_read) {
  auto camera = open_started_camera(uri);
  if (!camera) return camera.failure();
  RgbdFrame frame;
  frames_read = 0;
  const auto start = Clock::now();
  while (frames_read < max_frames) {
    auto status = (*camera)->next_frame(frame, std::chrono::milliseconds(2000));
    if (!status) return status.failure();
    if (*status == FrameStatus::kEndOfStream) break;
    if (*status == FrameStatus::kFrame) ++frames_read;
  }
  const double seconds = seconds_since(start);
  if (frames_read == 0) return fail("camera '" + uri + "' delivered no frames");
  return static_cast<double>(frames_read) / seconds;
}

int run_bench_camera(const ParsedOptions& options) {
  auto frames = options.get_int("frames");
  if (!frames) return report_failure(frames.error());
  if (*frames <= 0) return report_failure({"--frames must be at least 1"});
  const std::string synthetic_uri = "synthetic:seed=0,frames=" + std::to_string(*frames);

  nlohmann::json result;
  long long read = 0;
  std::cerr << "bench camera: synthetic, " << *frames << " frames...\n";
  auto synthetic_fps = measure_fps(synthetic_uri, *frames, read);
  if (!synthetic_fps) return report_failure(synthetic_fps.error());
  result["synthetic_fps"] = *synthetic_fps;
  result["synthetic_frames"] = read;
  result["synthetic_uri"] = synthetic_uri;

  auto scratch = ScratchDirectory::create("facebooth-bench-");
  if (!scratch) return report_failure(scratch.error());
  std::string replay_dir = options.get("replay");
  if (replay_dir.empty()) {
    std::cerr << "bench camera: recording the synthetic take to " << scratch->path() << "...\n";
    auto camera = open_camera(synthetic_uri);
    if (!camera) return report_failure(camera.error());
    RecorderOptions record_options;
    record_options.overwrite = true;  // the scratch directory is ours
    auto recorded = record_camera(**camera, scratch->path(), *frames, {}, record_options);
    if (!recorded) return report_failure(recorded.error());
    replay_dir = scratch->path().string();
  }
  std::cerr << "bench camera: replay of " << replay_dir << "...\n";
  auto replay_fps = measure_fps("replay:" + replay_dir, *frames, read);
  if (!replay_fps) return report_failure(replay_fps.error());
  result["replay_fps"] = *replay_fps;
  result["replay_frames"] = read;
  result["replay_source"] = options.get("replay").empty() ? "synthetic dump" : replay_dir;
  result["threads"] = 1;
  std::cout << result.dump(2) << std::endl;
  return kExitOk;
}

}  // namespace

std::vector<Command> bench_camera_commands() {
  return {
      {{"bench camera",
        "frames per second of the synthetic and replay backends (one core)",
        "Prints one JSON object on stdout: synthetic_fps, replay_fps and the frame counts.\n"
        "Without --replay, the replay figure uses a fakenect dump recorded from the synthetic "
        "take.",
        {{"frames", "N", "frames to read from each source", "90"},
         {"replay", "DIR", "time this fakenect dump instead of a recorded synthetic take", ""},
         {"json", "", "print JSON (the only output format; accepted for symmetry)", ""}}},
       run_bench_camera},
  };
}

}  // namespace fb::cli
