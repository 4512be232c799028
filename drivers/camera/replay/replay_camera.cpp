#include "drivers/camera/replay/replay_camera.hpp"

#include <chrono>
#include <string>
#include <thread>

#include "drivers/camera/common/camera_uri.hpp"
#include "drivers/camera/common/fakenect_dump.hpp"

namespace fb {
namespace {

using Clock = std::chrono::steady_clock;

class ReplayCamera final : public DepthCamera {
 public:
  ReplayCamera(CameraInfo info, FakenectDumpReader reader, const ReplayOptions& options)
      : info_(std::move(info)),
        reader_(std::move(reader)),
        registration_(info_.calibration),
        options_(options) {}

  const CameraInfo& info() const override { return info_; }

  Result<void> start() override {
    reader_.rewind();
    next_index_ = 0;
    started_ = true;
    pacing_started_ = false;
    return success();
  }

  void stop() override { started_ = false; }

  Result<FrameStatus> next_frame(RgbdFrame& frame, std::chrono::milliseconds timeout) override {
    if (!started_) {
      return fail("replay camera '" + info_.uri + "' is not started; call start() first");
    }
    const auto delivered = static_cast<long long>(next_index_);
    if (options_.fail_after >= 0 && delivered >= options_.fail_after)
      return fail("replay: the camera failed after " + std::to_string(delivered) +
                  " frames (fault injected by fail_after)");
    if (options_.stall_after >= 0 && delivered >= options_.stall_after) {
      std::this_thread::sleep_for(timeout);  // a stalled stream: nothing arrives
      return FrameStatus::kTimeout;
    }
    if (reader_.position() >= reader_.depth_frame_count()) {
      if (!options_.loop) return FrameStatus::kEndOfStream;
      reader_.rewind();
      pacing_started_ = false;  // the recorded clock jumps back; pace from here again
    }
    if (options_.realtime) {
      const double host_time = reader_.depth_host_time(reader_.position());
      if (!pacing_started_) {
        pacing_started_ = true;
        wall_start_ = Clock::now();
        host_start_ = host_time;
      }
      const auto due = wall_start_ + std::chrono::duration_cast<Clock::duration>(
                                         std::chrono::duration<double>(host_time - host_start_));
      const auto now = Clock::now();
      if (due > now) {
        if (due - now > timeout) {
          std::this_thread::sleep_for(timeout);
          return FrameStatus::kTimeout;
        }
        std::this_thread::sleep_until(due);
      }
    }
    auto got = reader_.next(frame);
    if (!got) return got.failure();
    if (!*got) return FrameStatus::kEndOfStream;  // not reached: position was checked above
    registration_.disparity_to_mm(frame.raw_disparity, frame.depth_mm);
    frame.index = next_index_++;
    return FrameStatus::kFrame;
  }

 private:
  CameraInfo info_;
  FakenectDumpReader reader_;
  KinectRegistration registration_;
  ReplayOptions options_;
  bool started_ = false;
  std::uint64_t next_index_ = 0;
  bool pacing_started_ = false;
  Clock::time_point wall_start_{};
  double host_start_ = 0.0;
};

constexpr std::string_view kUsage =
    "replay:DIR[,realtime=1][,loop=1][,stall_after=N|fail_after=N]  play a fakenect dump "
    "directory (INDEX.txt + d-/r- files); stall_after/fail_after inject a stalled or failed stream";

Result<std::unique_ptr<DepthCamera>> open_replay(std::string_view arguments) {
  if (arguments.empty()) {
    return fail("replay needs a dump directory: use " + std::string(kUsage));
  }
  auto parsed = split_recording_options(arguments, "replay");
  if (!parsed) return parsed.failure();
  return open_replay_camera(parsed->first, parsed->second);
}

std::vector<CameraListing> list_replay() {
  // A replay needs a path; there is nothing to enumerate.
  return {};
}

}  // namespace

Result<std::unique_ptr<DepthCamera>> open_replay_camera(const std::filesystem::path& directory,
                                                        const ReplayOptions& options) {
  auto reader = FakenectDumpReader::open(directory);
  if (!reader) return fail("replay: " + reader.error().message);
  const std::size_t n = reader->depth_frame_count();
  if (n == 0) {
    return fail("replay: fakenect dump '" + directory.string() +
                "' has no depth frames (INDEX.txt lists no d-*.pgm files)");
  }
  // Read the first frame now so a corrupt dump fails at open, and to learn the image size.
  RgbdFrame first;
  auto got = reader->next(first);
  if (!got) return fail("replay: " + got.error().message);
  reader->rewind();

  CameraInfo info;
  info.uri = "replay:" + directory.string();
  if (options.realtime) info.uri += ",realtime=1";
  if (options.loop) info.uri += ",loop=1";
  info.backend = "replay";
  const bool has_json = reader->device_calibration().has_value();
  info.calibration = has_json ? *reader->device_calibration() : KinectCalibration::typical_unit();
  info.depth_intrinsics = info.calibration.depth_intrinsics();
  info.width = first.raw_disparity.width;
  info.height = first.raw_disparity.height;
  const double span = reader->depth_host_time(n - 1) - reader->depth_host_time(0);
  info.fps = (n > 1 && span > 0.0) ? static_cast<double>(n - 1) / span : kKinectFps;
  info.frame_count = options.loop ? -1 : static_cast<long long>(n);
  info.description =
      "fakenect dump " + directory.string() + ": " + std::to_string(n) + " depth frames, " +
      std::to_string(reader->color_image_count()) + " colour images, calibration from " +
      (has_json ? std::string("device.json")
                : std::string("defaults for a typical unit (no device.json; run `facebooth "
                              "camera self-calibrate --camera replay:DIR --save`)"));
  return std::unique_ptr<DepthCamera>(
      std::make_unique<ReplayCamera>(std::move(info), std::move(*reader), options));
}

CameraBackend replay_camera_backend() {
  return {"replay", &open_replay, &list_replay, kUsage};
}

}  // namespace fb
