#include "drivers/camera/recorder/recorder.hpp"

#include <string>

namespace fb {

struct FakenectRecorder::State {
  State(FakenectDumpWriter w, const CameraInfo& camera)
      : writer(std::move(w)), registration(camera.calibration), fps(camera.fps) {}

  FakenectDumpWriter writer;
  KinectRegistration registration;
  double fps = kKinectFps;
  DisparityImage converted;  // reused when depth comes as millimetres only
  bool have_color = false;
  double last_color_time = 0.0;
  std::uint32_t last_color_timestamp = 0;
  RecordSummary summary;
  bool finished = false;
};

FakenectRecorder::FakenectRecorder(std::unique_ptr<State> state) : state_(std::move(state)) {}
FakenectRecorder::FakenectRecorder(FakenectRecorder&&) noexcept = default;
FakenectRecorder& FakenectRecorder::operator=(FakenectRecorder&&) noexcept = default;
FakenectRecorder::~FakenectRecorder() = default;

Result<FakenectRecorder> FakenectRecorder::create(const std::filesystem::path& directory,
                                                  const CameraInfo& camera,
                                                  const RecorderOptions& options) {
  DumpWriterOptions writer_options;
  writer_options.overwrite = options.overwrite;
  writer_options.sync_each_entry = options.sync_each_entry;
  auto writer = FakenectDumpWriter::create(directory, camera.calibration, writer_options);
  if (!writer) return writer.failure();
  auto state = std::make_unique<State>(std::move(*writer), camera);
  if (!(state->fps > 0.0)) state->fps = kKinectFps;
  state->summary.directory = directory;
  state->converted.resize(camera.width > 0 ? camera.width : kKinectWidth,
                          camera.height > 0 ? camera.height : kKinectHeight);
  return FakenectRecorder(std::move(state));
}

Result<void> FakenectRecorder::write(const RgbdFrame& frame) {
  State& s = *state_;
  if (s.finished)
    return fail("the recording in '" + s.summary.directory.string() + "' is finished");
  double depth_time = frame.depth_host_time_s;
  if (!(depth_time > 0.0)) depth_time = static_cast<double>(frame.index) / s.fps;

  if (!frame.color.empty()) {
    const bool unstamped = frame.color_host_time_s == 0.0 && frame.color_device_timestamp == 0;
    const bool is_new = unstamped || !s.have_color ||
                        frame.color_host_time_s != s.last_color_time ||
                        frame.color_device_timestamp != s.last_color_timestamp;
    if (is_new) {
      const double color_time =
          frame.color_host_time_s > 0.0 ? frame.color_host_time_s : depth_time;
      if (auto r = s.writer.write_color(frame.color, color_time, frame.color_device_timestamp);
          !r) {
        return r;
      }
      s.have_color = true;
      s.last_color_time = frame.color_host_time_s;
      s.last_color_timestamp = frame.color_device_timestamp;
      ++s.summary.color_images;
    }
  }

  const DisparityImage* raw = &frame.raw_disparity;
  if (raw->empty()) {
    if (frame.depth_mm.empty()) {
      return fail("frame " + std::to_string(frame.index) +
                  " has neither raw disparity nor depth; nothing to record");
    }
    s.registration.mm_to_disparity(frame.depth_mm, s.converted);
    raw = &s.converted;
  }
  if (auto r = s.writer.write_depth(*raw, depth_time, frame.depth_device_timestamp); !r) return r;
  if (s.summary.depth_frames == 0) s.summary.first_host_time_s = depth_time;
  s.summary.last_host_time_s = depth_time;
  ++s.summary.depth_frames;
  return success();
}

Result<RecordSummary> FakenectRecorder::finish() {
  State& s = *state_;
  if (!s.finished) {
    s.finished = true;
    if (auto r = s.writer.finish(); !r) return r.failure();
  }
  return s.summary;
}

const RecordSummary& FakenectRecorder::summary() const {
  return state_->summary;
}

Result<RecordSummary> record_camera(DepthCamera& camera, const std::filesystem::path& directory,
                                    long long max_frames,
                                    const std::function<void(long long)>& progress,
                                    const RecorderOptions& options) {
  auto recorder = FakenectRecorder::create(directory, camera.info(), options);
  if (!recorder) return recorder.failure();
  if (auto r = camera.start(); !r) {
    return fail("cannot start camera '" + camera.info().uri +
                "' for recording: " + r.error().message);
  }
  // Stops the camera and seals the dump on every exit path.
  struct StopGuard {
    DepthCamera& camera;
    ~StopGuard() { camera.stop(); }
  } stop_guard{camera};

  const auto failed = [&](const std::string& what) {
    (void)recorder->finish();
    return fail(what + " (" + std::to_string(recorder->summary().depth_frames) +
                " frames recorded so far in '" + directory.string() + "' remain a valid dump)");
  };

  RgbdFrame frame;
  int timeouts = 0;
  bool end_of_stream = false;
  while (max_frames <= 0 || recorder->summary().depth_frames < max_frames) {
    auto status = camera.next_frame(frame, options.frame_timeout);
    if (!status) return failed("camera error: " + status.error().message);
    if (*status == FrameStatus::kEndOfStream) {
      end_of_stream = true;
      break;
    }
    if (*status == FrameStatus::kTimeout) {
      if (++timeouts >= options.max_consecutive_timeouts) {
        return failed("camera '" + camera.info().uri + "' delivered no frame for " +
                      std::to_string(timeouts) + " x " +
                      std::to_string(options.frame_timeout.count()) + " ms");
      }
      continue;
    }
    timeouts = 0;
    if (auto r = recorder->write(frame); !r) return failed(r.error().message);
    if (progress) progress(recorder->summary().depth_frames);
  }
  auto summary = recorder->finish();
  if (!summary) return summary.failure();
  summary->end_of_stream = end_of_stream;
  return summary;
}

}  // namespace fb
