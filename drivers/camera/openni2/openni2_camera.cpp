#include "drivers/camera/openni2/openni2_camera.hpp"

#include <OpenNI.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>
#include <system_error>
#include <thread>

#include "drivers/camera/common/camera_uri.hpp"
#include "drivers/camera/common/host_clock.hpp"
#include "drivers/camera/openni2/oni_writer.hpp"

namespace fb {
namespace {

constexpr std::string_view kBackend = "openni2";

// Field of view a PS1080 (Kinect v1 class) depth camera reports; used when a stream has none
// (OpenNI's DummyDevice, some third-party drivers) so intrinsics stay plausible.
constexpr double kFallbackHfov = kPs1080DepthHfov;
constexpr double kFallbackVfov = kPs1080DepthVfov;

const char* status_name(openni::Status rc) {
  switch (rc) {
    case openni::STATUS_OK:
      return "OK";
    case openni::STATUS_ERROR:
      return "ERROR";
    case openni::STATUS_NOT_IMPLEMENTED:
      return "NOT_IMPLEMENTED";
    case openni::STATUS_NOT_SUPPORTED:
      return "NOT_SUPPORTED";
    case openni::STATUS_BAD_PARAMETER:
      return "BAD_PARAMETER";
    case openni::STATUS_OUT_OF_FLOW:
      return "OUT_OF_FLOW";
    case openni::STATUS_NO_DEVICE:
      return "NO_DEVICE";
    case openni::STATUS_TIME_OUT:
      return "TIME_OUT";
  }
  return "unknown";
}

// OpenNI's status plus its per-thread extended error text (which comes as tab-indented lines),
// flattened to one line. Must be called right after the failing call: any OpenNI call clears it.
std::string openni_error(openni::Status rc) {
  std::string text = openni::OpenNI::getExtendedError();
  std::string flat;
  for (char c : text) {
    if (c == '\n' || c == '\r' || c == '\t') {
      if (!flat.empty() && flat.back() != ' ' && flat.back() != ';') flat += "; ";
    } else {
      flat += c;
    }
  }
  while (!flat.empty() && (flat.back() == ' ' || flat.back() == ';')) flat.pop_back();
  std::string message =
      "OpenNI status " + std::to_string(static_cast<int>(rc)) + " (" + status_name(rc) + ")";
  if (!flat.empty()) message += ": " + flat;
  return message;
}

// Keeps OpenNI initialized while it is alive. OpenNI::initialize/shutdown are reference-counted
// inside the library (Context::m_initializationCounter), so every holder owns one
// initialize/shutdown pair and no process-wide state is needed on our side: OpenNI is loaded
// while any camera (or list()) holds a runtime and unloaded when the last one goes.
// The library's counter is a plain int, so cameras must be opened and destroyed from one thread
// at a time (as the daemon and the host tool do). Also note that the first initialize()
// temporarily changes the process's working directory while it loads the drivers.
class OpenNiRuntime {
 public:
  static Result<std::shared_ptr<OpenNiRuntime>> acquire() {
    const openni::Status rc = openni::OpenNI::initialize();
    if (rc != openni::STATUS_OK) {
      std::string error = openni_error(rc);
      // initialize() counted this call even though it failed; balance it.
      openni::OpenNI::shutdown();
      return fail("openni2: cannot initialize OpenNI2 (" + error +
                  "). Check that the OpenNI2 drivers are installed (Debian: libopenni2-0 puts "
                  "them in /usr/lib/<arch>/OpenNI2/Drivers) and that OpenNI.ini is readable");
    }
    return std::shared_ptr<OpenNiRuntime>(new OpenNiRuntime());
  }
  ~OpenNiRuntime() { openni::OpenNI::shutdown(); }
  OpenNiRuntime(const OpenNiRuntime&) = delete;
  OpenNiRuntime& operator=(const OpenNiRuntime&) = delete;

 private:
  OpenNiRuntime() = default;
};

bool ends_with_oni(std::string_view text) {
  if (text.size() < 4) return false;
  std::string tail(text.substr(text.size() - 4));
  std::transform(tail.begin(), tail.end(), tail.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return tail == ".oni";
}

bool is_recording_argument(std::string_view arguments) {
  if (arguments.empty()) return false;
  if (ends_with_oni(arguments)) return true;
  std::error_code ec;
  return std::filesystem::is_regular_file(std::filesystem::path(arguments), ec);
}

std::string pixel_format_name(openni::PixelFormat format) {
  switch (format) {
    case openni::PIXEL_FORMAT_DEPTH_1_MM:
      return "DEPTH_1_MM";
    case openni::PIXEL_FORMAT_DEPTH_100_UM:
      return "DEPTH_100_UM";
    case openni::PIXEL_FORMAT_SHIFT_9_2:
      return "SHIFT_9_2";
    case openni::PIXEL_FORMAT_SHIFT_9_3:
      return "SHIFT_9_3";
    case openni::PIXEL_FORMAT_RGB888:
      return "RGB888";
    case openni::PIXEL_FORMAT_YUV422:
      return "YUV422";
    case openni::PIXEL_FORMAT_GRAY8:
      return "GRAY8";
    case openni::PIXEL_FORMAT_GRAY16:
      return "GRAY16";
    case openni::PIXEL_FORMAT_JPEG:
      return "JPEG";
    case openni::PIXEL_FORMAT_YUYV:
      return "YUYV";
  }
  return "format " + std::to_string(static_cast<int>(format));
}

std::string describe(const openni::VideoMode& mode) {
  return std::to_string(mode.getResolutionX()) + "x" + std::to_string(mode.getResolutionY()) + "@" +
         std::to_string(mode.getFps()) + " " + pixel_format_name(mode.getPixelFormat());
}

// Picks a live sensor's mode: one of `formats` (in order of preference), 640x480 at 30 fps if
// offered (what the pipeline is tuned for), otherwise the largest 30 fps mode, otherwise any.
bool choose_mode(const openni::SensorInfo& sensor,
                 std::initializer_list<openni::PixelFormat> formats, openni::VideoMode& chosen) {
  const auto& modes = sensor.getSupportedVideoModes();
  long best_score = -1;
  for (int i = 0; i < modes.getSize(); ++i) {
    const openni::VideoMode& mode = modes[i];
    long format_rank = -1;
    long rank = 0;
    for (openni::PixelFormat format : formats) {
      if (mode.getPixelFormat() == format) format_rank = rank;
      ++rank;
    }
    if (format_rank < 0) continue;
    const long pixels = static_cast<long>(mode.getResolutionX()) * mode.getResolutionY();
    long score = (10 - format_rank) * 100000000L;
    if (mode.getResolutionX() == kKinectWidth && mode.getResolutionY() == kKinectHeight)
      score += 50000000L;
    if (mode.getFps() == 30) score += 20000000L;
    score += std::min(pixels, 19999999L);
    if (score > best_score) {
      best_score = score;
      chosen = mode;
    }
  }
  return best_score >= 0;
}

PinholeIntrinsics intrinsics_from_fov(int width, int height, double hfov, double vfov) {
  constexpr double kPi = 3.14159265358979323846;
  if (!(hfov > 0.0 && hfov < kPi) || !(vfov > 0.0 && vfov < kPi)) {
    hfov = kFallbackHfov;
    vfov = kFallbackVfov;
  }
  PinholeIntrinsics k;
  k.width = width;
  k.height = height;
  k.fx = width / (2.0 * std::tan(hfov / 2.0));
  k.fy = height / (2.0 * std::tan(vfov / 2.0));
  // OpenNI's own depth<->world conversion puts the optical axis at (width/2, height/2).
  k.cx = width / 2.0;
  k.cy = height / 2.0;
  return k;
}

class Openni2Camera final : public DepthCamera {
 public:
  explicit Openni2Camera(std::shared_ptr<OpenNiRuntime> runtime) : runtime_(std::move(runtime)) {}

  ~Openni2Camera() override {
    if (playback_ && device_.isValid() && !player_seen_running_) ensure_player_thread_running();
    // Order matters: frame references go back to their streams, streams are destroyed before
    // the device that created them (closing a recording's device first frees OpenNI's device
    // object under the streams), and OpenNI itself is released last (runtime_).
    // Known residue: libOniFile's player thread walks its stream list every 10 ms without the
    // lock that stream destruction skips too; with the streams stopped that window is tiny.
    stop();
    color_.destroy();
    depth_.destroy();
    device_.close();
  }

  Result<void> open(std::string_view arguments) {
    // `FILE.oni,loop=1,realtime=1`: the same options as replay (camera_uri.hpp).
    auto split = split_recording_options(arguments, kBackend);
    if (!split) return split.failure();
    const std::string target = split->first;
    options_ = split->second;
    info_.backend = std::string(kBackend);
    playback_ = is_recording_argument(target);
    info_.uri = std::string(kBackend) + ":" + target + (options_.realtime ? ",realtime=1" : "") +
                (options_.loop ? ",loop=1" : "");
    if (options_.stall_after >= 0 || options_.fail_after >= 0)
      return fail(
          "openni2: stall_after and fail_after are fault injection of the replay backend "
          "only (replay:DIR,stall_after=N)");
    if (!playback_ && (options_.loop || options_.realtime)) {
      return fail("openni2: '" + target +
                  "' is not a recording; loop and realtime apply to recordings only "
                  "(openni2:FILE.oni,loop=1,realtime=1)");
    }

    if (playback_) {
      std::error_code ec;
      const std::filesystem::path path(target);
      if (!std::filesystem::exists(path, ec)) {
        return fail("openni2: recording '" + target +
                    "' does not exist; check the path (openni2:PATH.oni)");
      }
      if (!std::filesystem::is_regular_file(path, ec)) {
        return fail("openni2: '" + target +
                    "' is not a file; openni2:PATH expects an .oni recording");
      }
    }

    const openni::Status rc = device_.open(target.empty() ? openni::ANY_DEVICE : target.c_str());
    if (rc != openni::STATUS_OK) {
      const std::string error = openni_error(rc);
      if (playback_) {
        return fail("openni2: cannot play '" + target + "' (" + error +
                    "). The file is not an .oni recording libOniFile can read: its header is "
                    "missing, damaged or truncated");
      }
      if (target.empty()) {
        return fail("openni2: no OpenNI2 device found (" + error +
                    "). Connect a Kinect/PrimeSense/Xtion sensor and check the USB permissions "
                    "(udev rules), or play a recording with openni2:PATH.oni");
      }
      return fail("openni2: cannot open device '" + target + "' (" + error +
                  "). Check the URI against `facebooth camera list` and that the sensor is "
                  "connected");
    }

    if (playback_) {
      if (auto ok = configure_playback(target); !ok) return ok;
    }
    if (auto ok = create_streams(target); !ok) return ok;
    return success();
  }

  const CameraInfo& info() const override { return info_; }

  Result<void> start() override {
    if (started_) return success();
    if (ended_) {
      return fail("openni2: recording '" + device_uri_ +
                  "' has been played to its end; open the camera again to replay it");
    }
    // With manual stepping the player hands out records in file order and waits for a reader;
    // every stream must be started before any is read, or the player blocks on a stream
    // nobody reads (and frames for unstarted streams are dropped).
    openni::Status rc = depth_.start();
    if (rc != openni::STATUS_OK) {
      return fail("openni2: cannot start the depth stream of '" + device_uri_ + "' (" +
                  openni_error(rc) + ")");
    }
    if (has_color_) {
      rc = color_.start();
      if (rc != openni::STATUS_OK) {
        std::string error = openni_error(rc);
        depth_.stop();
        return fail("openni2: cannot start the colour stream of '" + device_uri_ + "' (" + error +
                    ")");
      }
    }
    started_ = true;
    pacing_started_ = false;
    return success();
  }

  void stop() override {
    pending_depth_.release();
    pending_color_.release();
    latest_color_.release();
    if (!started_) return;
    if (has_color_) color_.stop();
    depth_.stop();
    started_ = false;
  }

  Result<FrameStatus> next_frame(RgbdFrame& frame, std::chrono::milliseconds timeout) override {
    if (ended_) return FrameStatus::kEndOfStream;
    if (!started_) return fail("openni2: next_frame() called before start()");

    using Clock = std::chrono::steady_clock;
    const auto deadline = Clock::now() + std::max(timeout, std::chrono::milliseconds(0));
    openni::VideoStream* streams[2] = {&depth_, &color_};
    const int stream_count = has_color_ ? 2 : 1;

    for (;;) {
      const bool depth_exhausted = playback_ && last_depth_index_ >= depth_frame_count_;
      const bool color_exhausted = playback_ && last_color_index_ >= color_frame_count_;
      if (!pending_depth_.isValid() && depth_exhausted) {
        finish_playback();
        return FrameStatus::kEndOfStream;
      }
      bool need_color = has_color_ && !pending_color_.isValid() && !color_exhausted;
      // A live colour camera that stalls must not hold depth back forever: after two frame
      // periods the depth goes out with the latest colour. Recordings always wait (the colour
      // frame is the next record in the file).
      auto wait_until = deadline;
      if (need_color && !playback_ && pending_depth_.isValid()) {
        const auto color_deadline = depth_read_at_ + max_color_lag_;
        if (Clock::now() >= color_deadline) need_color = false;
        wait_until = std::min(wait_until, color_deadline);
      }
      if (pending_depth_.isValid() && !need_color) {
        if (options_.realtime && !paced(pending_depth_.getTimestamp(), deadline))
          return FrameStatus::kTimeout;  // the frame stays pending until it is due
        auto ok = deliver(frame);
        if (!ok) {
          pending_depth_.release();  // skip the bad frame rather than failing on it forever
          return ok.failure();
        }
        return FrameStatus::kFrame;
      }

      const auto remaining =
          std::chrono::duration_cast<std::chrono::milliseconds>(wait_until - Clock::now());
      const int wait_ms = static_cast<int>(std::clamp<long long>(remaining.count(), 0, INT_MAX));
      int ready = -1;
      // Waiting on every stream (not only the one still missing) matters for recordings: the
      // player delivers records in file order, and a frame for a stream we are not waiting on
      // would not wake us, costing the whole timeout.
      // Except when a recording's depth frame is already pending: then only its colour is
      // wanted, and a depth frame the player has run ahead with (at the end of the file, the
      // first frame of the next loop) must stay unread rather than replace the pending one.
      const bool color_only = playback_ && pending_depth_.isValid();
      const openni::Status rc =
          color_only ? openni::OpenNI::waitForAnyStream(streams + 1, 1, &ready, wait_ms)
                     : openni::OpenNI::waitForAnyStream(streams, stream_count, &ready, wait_ms);
      if (rc == openni::STATUS_OK && color_only) ready = ready == 0 ? 1 : -1;
      if (rc == openni::STATUS_TIME_OUT) {
        if (Clock::now() >= deadline) return FrameStatus::kTimeout;
        continue;  // the colour lag ran out (or the wait woke early): re-evaluate
      }
      if (rc != openni::STATUS_OK || ready < 0 || ready >= stream_count) {
        return fail("openni2: waiting for frames from '" + device_uri_ + "' failed (" +
                    openni_error(rc) + "); the device may have been unplugged");
      }
      // A newer frame replaces an unconsumed one of the same stream: live devices deliver
      // depth and colour independently, and the newest pair is what the caller wants.
      openni::VideoFrameRef& target = ready == 0 ? pending_depth_ : pending_color_;
      const openni::Status read = streams[ready]->readFrame(&target);
      if (read != openni::STATUS_OK || !target.isValid()) {
        return fail("openni2: reading a " + std::string(ready == 0 ? "depth" : "colour") +
                    " frame from '" + device_uri_ + "' failed (" + openni_error(read) + ")");
      }
      (ready == 0 ? last_depth_index_ : last_color_index_) = target.getFrameIndex();
      player_seen_running_ = true;
      if (ready == 0) depth_read_at_ = Clock::now();
    }
  }

 private:
  Result<void> configure_playback(const std::string& path) {
    openni::PlaybackControl* control = device_.getPlaybackControl();  // owned by device_
    if (control == nullptr) {
      return fail("openni2: '" + path + "' opened but is not a recording (no playback control)");
    }
    // Manual stepping: frames come when the reader asks, so none is dropped and playback runs
    // as fast as the consumer.
    //
    // Repeat stays ON although the recording plays once: the end of the stream is detected from
    // the frame counts (PlaybackControl::getNumberOfFrames vs frame indices), and the streams are
    // stopped after the last frame. With repeat off, libOniFile's player thread, on reaching the
    // file's End record, reports EOF to OpenNI's core from its own thread (which races with
    // Device::close and crashed about one run in five here) and then spins on the closed file.
    // With repeat on it rewinds and waits politely for a manual trigger that never comes.
    openni::Status rc = control->setSpeed(-1.0f);
    if (rc == openni::STATUS_OK) rc = control->setRepeatEnabled(true);
    if (rc != openni::STATUS_OK) {
      return fail("openni2: cannot set up playback of '" + path + "' (" + openni_error(rc) + ")");
    }
    return success();
  }

  // Asks a live sensor for the preferred mode. The caller checks the resulting pixel format, so
  // a sensor without any acceptable mode is reported there.
  Result<void> configure_live_mode(openni::VideoStream& stream, openni::SensorType type,
                                   std::initializer_list<openni::PixelFormat> formats,
                                   const char* what) {
    const openni::SensorInfo* sensor = device_.getSensorInfo(type);
    openni::VideoMode wanted;
    if (sensor == nullptr || !choose_mode(*sensor, formats, wanted)) return success();
    const openni::VideoMode current = stream.getVideoMode();
    const bool same = current.getPixelFormat() == wanted.getPixelFormat() &&
                      current.getResolutionX() == wanted.getResolutionX() &&
                      current.getResolutionY() == wanted.getResolutionY() &&
                      current.getFps() == wanted.getFps();
    if (!same) {
      const openni::Status rc = stream.setVideoMode(wanted);
      const bool current_usable =
          std::find(formats.begin(), formats.end(), current.getPixelFormat()) != formats.end();
      // Some drivers (OpenNI's DummyDevice among them) cannot switch modes; their current mode
      // is fine as long as its pixel format is one we read.
      if (rc != openni::STATUS_OK && !current_usable) {
        return fail("openni2: '" + device_uri_ + "' refused " + what + " mode " + describe(wanted) +
                    " (" + openni_error(rc) + ")");
      }
    }
    // The pipeline expects images as the camera sees them (as libfreenect delivers them);
    // PrimeSense firmware mirrors by default. Drivers without the property keep their default.
    (void)stream.setMirroringEnabled(false);
    return success();
  }

  Result<void> create_streams(const std::string& target) {
    const openni::DeviceInfo& device_info = device_.getDeviceInfo();
    device_uri_ = device_info.getUri();
    if (!device_.hasSensor(openni::SENSOR_DEPTH)) {
      return fail("openni2: '" + device_uri_ + "' has no depth stream; facebooth needs depth");
    }
    openni::Status rc = depth_.create(device_, openni::SENSOR_DEPTH);
    if (rc != openni::STATUS_OK) {
      return fail("openni2: cannot create the depth stream of '" + device_uri_ + "' (" +
                  openni_error(rc) + ")");
    }
    if (!playback_) {
      // Recordings keep the mode they were recorded with; live sensors are asked for one.
      auto ok = configure_live_mode(
          depth_, openni::SENSOR_DEPTH,
          {openni::PIXEL_FORMAT_DEPTH_1_MM, openni::PIXEL_FORMAT_DEPTH_100_UM}, "depth");
      if (!ok) return ok;
    }
    const openni::VideoMode depth_mode = depth_.getVideoMode();
    const auto depth_format = depth_mode.getPixelFormat();
    if (depth_format != openni::PIXEL_FORMAT_DEPTH_1_MM &&
        depth_format != openni::PIXEL_FORMAT_DEPTH_100_UM) {
      return fail("openni2: depth stream of '" + device_uri_ + "' is " + describe(depth_mode) +
                  "; only DEPTH_1_MM and DEPTH_100_UM are supported");
    }
    depth_is_100um_ = depth_format == openni::PIXEL_FORMAT_DEPTH_100_UM;

    has_color_ = device_.hasSensor(openni::SENSOR_COLOR);
    if (has_color_) {
      rc = color_.create(device_, openni::SENSOR_COLOR);
      if (rc != openni::STATUS_OK) {
        return fail("openni2: cannot create the colour stream of '" + device_uri_ + "' (" +
                    openni_error(rc) + ")");
      }
      if (!playback_) {
        auto ok = configure_live_mode(color_, openni::SENSOR_COLOR, {openni::PIXEL_FORMAT_RGB888},
                                      "colour");
        if (!ok) return ok;
      }
      const openni::VideoMode color_mode = color_.getVideoMode();
      if (color_mode.getPixelFormat() != openni::PIXEL_FORMAT_RGB888) {
        return fail("openni2: colour stream of '" + device_uri_ + "' is " + describe(color_mode) +
                    "; only RGB888 is supported");
      }
    }

    if (playback_) {
      const openni::PlaybackControl* control = device_.getPlaybackControl();
      depth_frame_count_ = control->getNumberOfFrames(depth_);
      color_frame_count_ = has_color_ ? control->getNumberOfFrames(color_) : 0;
    }

    info_.width = depth_mode.getResolutionX();
    info_.height = depth_mode.getResolutionY();
    info_.fps = depth_mode.getFps() > 0 ? depth_mode.getFps() : kKinectFps;
    max_color_lag_ = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
        std::chrono::duration<double>(2.0 / info_.fps));
    // OpenNI2 exposes no Kinect reg_info / zero-plane block, so a typical Kinect v1 unit
    // stands in; it only matters to code that converts disparity or registers depth to colour
    // with the Kinect model (self-calibration refines it per unit).
    info_.calibration = KinectCalibration::typical_unit();
    info_.depth_intrinsics =
        intrinsics_from_fov(info_.width, info_.height, depth_.getHorizontalFieldOfView(),
                            depth_.getVerticalFieldOfView());
    info_.frame_count = playback_ && !options_.loop ? depth_frame_count_ : -1;
    if (playback_) {
      info_.description = "OpenNI2 recording " + target + " (" +
                          std::to_string(depth_frame_count_) + " frames, " + describe(depth_mode) +
                          (has_color_ ? ", colour" : "") + (options_.loop ? ", looped" : "") +
                          (options_.realtime ? ", at the recorded pace" : "") + ")";
    } else {
      std::string name = device_info.getVendor();
      const std::string model = device_info.getName();
      if (!model.empty()) name += (name.empty() ? "" : " ") + model;
      info_.description = (name.empty() ? std::string("OpenNI2 device") : name) + " (" +
                          device_uri_ + ", " + describe(depth_mode) + ")";
    }
    return success();
  }

  Result<void> deliver(RgbdFrame& frame) {
    const openni::VideoFrameRef& depth = pending_depth_;
    const int w = depth.getWidth();
    const int h = depth.getHeight();
    const int stride = depth.getStrideInBytes();
    if (w <= 0 || h <= 0 || stride < w * 2 || depth.getDataSize() < stride * (h - 1) + w * 2) {
      return fail("openni2: depth frame " + std::to_string(depth.getFrameIndex()) + " from '" +
                  device_uri_ + "' has an inconsistent size (" + std::to_string(w) + "x" +
                  std::to_string(h) + ", " + std::to_string(depth.getDataSize()) + " bytes)");
    }
    frame.depth_mm.resize(w, h);  // no reallocation when the size repeats
    const auto* src = static_cast<const std::uint8_t*>(depth.getData());
    for (int y = 0; y < h; ++y) {
      std::uint16_t* row = frame.depth_mm.pixels.data() + static_cast<std::size_t>(y) * w;
      std::memcpy(row, src + static_cast<std::size_t>(y) * stride, static_cast<std::size_t>(w) * 2);
      if (depth_is_100um_) {
        for (int x = 0; x < w; ++x) row[x] = static_cast<std::uint16_t>((row[x] + 5) / 10);
      }
    }
    frame.raw_disparity.resize(0, 0);  // OpenNI2 delivers millimetres only

    if (pending_color_.isValid()) {
      latest_color_ = pending_color_;
      pending_color_.release();
    }
    if (latest_color_.isValid()) {
      const openni::VideoFrameRef& color = latest_color_;
      const int cw = color.getWidth();
      const int ch = color.getHeight();
      const int cstride = color.getStrideInBytes();
      if (cw <= 0 || ch <= 0 || cstride < cw * 3 ||
          color.getDataSize() < cstride * (ch - 1) + cw * 3) {
        return fail("openni2: colour frame " + std::to_string(color.getFrameIndex()) + " from '" +
                    device_uri_ + "' has an inconsistent size");
      }
      frame.color.resize(cw, ch);
      const auto* csrc = static_cast<const std::uint8_t*>(color.getData());
      for (int y = 0; y < ch; ++y) {
        std::memcpy(frame.color.pixels.data() + static_cast<std::size_t>(y) * cw,
                    csrc + static_cast<std::size_t>(y) * cstride, static_cast<std::size_t>(cw) * 3);
      }
      frame.color_device_timestamp = device_clock(color.getTimestamp());
      frame.color_host_time_s = host_time(color.getTimestamp());
    } else {
      frame.color.resize(0, 0);
    }

    frame.index = delivered_++;
    frame.depth_device_timestamp = device_clock(depth.getTimestamp());
    frame.depth_host_time_s = host_time(depth.getTimestamp());
    pending_depth_.release();

    // After the last frame of a recording, stop at once, so that frames of the player's next
    // loop (repeat is on, see configure_playback) go nowhere; with loop=1 those frames are the
    // next ones delivered.
    if (playback_ && last_depth_index_ >= depth_frame_count_ &&
        (!has_color_ || last_color_index_ >= color_frame_count_)) {
      if (options_.loop) {
        last_depth_index_ = last_color_index_ = 0;  // the player numbers the next loop from 1
        pacing_started_ = false;  // the recorded clock starts over: pace from here again
      } else {
        finish_playback();
      }
    }
    return success();
  }

  // realtime=1: waits until the recorded time of a frame (microseconds) is due on the wall
  // clock, counted from the first frame of the loop. False when that is after `deadline` (the
  // wait then ran to the deadline).
  bool paced(std::uint64_t timestamp_us, std::chrono::steady_clock::time_point deadline) {
    const auto now = std::chrono::steady_clock::now();
    if (!pacing_started_) {
      pacing_started_ = true;
      pacing_wall_start_ = now;
      pacing_recorded_start_us_ = timestamp_us;
    }
    const auto offset_us = timestamp_us >= pacing_recorded_start_us_
                               ? timestamp_us - pacing_recorded_start_us_
                               : std::uint64_t{0};
    const auto due = pacing_wall_start_ + std::chrono::microseconds(offset_us);
    if (due > deadline) {
      std::this_thread::sleep_until(deadline);
      return false;
    }
    std::this_thread::sleep_until(due);
    return true;
  }

  // OpenNI timestamps are microseconds of the device clock; the Kinect's native clock runs at
  // 60 MHz and is 32 bits wide, which is what RgbdFrame's device timestamps hold.
  static std::uint32_t device_clock(std::uint64_t microseconds) {
    return static_cast<std::uint32_t>(microseconds * 60u);
  }
  // Recordings carry no host time, so their timeline is the recorded timestamp; live frames are
  // stamped with the host's time when read (as fakenect dumps name their files; HostClock: a
  // clock set mid-stream does not make the frame times jump).
  double host_time(std::uint64_t microseconds) const {
    if (playback_) return static_cast<double>(microseconds) * 1e-6;
    return host_clock_.now_s();
  }

  // libOniFile's player thread sets its own "running" flag when it starts, so a device closed
  // before that thread was first scheduled never sees the stop request: close() waits 3 s, then
  // cancels the thread, which crashes the process (seen when a recording is opened and closed
  // at once, e.g. only to read its info, on a loaded machine). A delivered frame proves the
  // thread is up, so a camera that never read one reads one now.
  void ensure_player_thread_running() {
    const bool was_started = started_;
    if (!started_ && !start()) return;
    if (depth_frame_count_ > 0 || color_frame_count_ > 0) {
      openni::VideoStream* streams[2] = {&depth_, &color_};
      int ready = -1;
      if (openni::OpenNI::waitForAnyStream(streams, has_color_ ? 2 : 1, &ready, 2000) ==
              openni::STATUS_OK &&
          ready >= 0) {
        openni::VideoFrameRef discarded;
        (void)streams[ready]->readFrame(&discarded);
        player_seen_running_ = true;
      }
    }
    if (!player_seen_running_) {
      // An empty recording never delivers a frame; give the thread time to be scheduled.
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
    }
    if (!was_started) stop();
  }

  void finish_playback() {
    ended_ = true;
    stop();
  }

  // Declaration order is destruction order in reverse: runtime_ must outlive everything.
  std::shared_ptr<OpenNiRuntime> runtime_;
  openni::Device device_;
  openni::VideoStream depth_;
  openni::VideoStream color_;
  openni::VideoFrameRef pending_depth_;  // read but not yet delivered
  openni::VideoFrameRef pending_color_;
  openni::VideoFrameRef latest_color_;  // colour of the last delivered frame, reused if no newer
  CameraInfo info_;
  std::string device_uri_;
  RecordingOptions options_;  // loop, realtime (recordings only)
  const HostClock host_clock_;
  bool pacing_started_ = false;
  std::chrono::steady_clock::time_point pacing_wall_start_{};
  std::uint64_t pacing_recorded_start_us_ = 0;
  bool playback_ = false;
  bool has_color_ = false;
  bool depth_is_100um_ = false;
  bool started_ = false;
  bool ended_ = false;
  int depth_frame_count_ = 0;
  int color_frame_count_ = 0;
  int last_depth_index_ = 0;  // OpenNI frame indices; recordings number frames from 1
  int last_color_index_ = 0;
  std::uint64_t delivered_ = 0;
  bool player_seen_running_ = false;  // playback: a frame arrived, so the player thread runs
  std::chrono::steady_clock::time_point depth_read_at_;  // when pending_depth_ arrived
  std::chrono::steady_clock::duration max_color_lag_{};  // live: longest wait for colour
};

std::vector<CameraListing> list_openni2() {
  auto runtime = OpenNiRuntime::acquire();
  if (!runtime) return {};
  openni::Array<openni::DeviceInfo> devices;
  openni::OpenNI::enumerateDevices(&devices);
  std::vector<CameraListing> listings;
  for (int i = 0; i < devices.getSize(); ++i) {
    const openni::DeviceInfo& device = devices[i];
    // Recordings opened earlier in this process stay in OpenNI's device list; they are not
    // devices.
    if (ends_with_oni(device.getUri())) continue;
    char ids[32];
    std::snprintf(ids, sizeof(ids), "%04x:%04x", device.getUsbVendorId(), device.getUsbProductId());
    listings.push_back(
        {std::string(kBackend) + ":" + device.getUri(),
         std::string(device.getVendor()) + " " + device.getName() + " (USB " + ids + ")"});
  }
  return listings;
}

}  // namespace

Result<std::unique_ptr<DepthCamera>> open_openni2_camera(std::string_view arguments) {
  auto runtime = OpenNiRuntime::acquire();
  if (!runtime) return runtime.failure();
  auto camera = std::make_unique<Openni2Camera>(std::move(*runtime));
  if (auto ok = camera->open(arguments); !ok) return ok.failure();
  return std::unique_ptr<DepthCamera>(std::move(camera));
}

CameraBackend openni2_camera_backend() {
  return {kBackend, &open_openni2_camera, &list_openni2,
          "openni2:[URI|PATH.oni[,realtime=1][,loop=1]]  OpenNI2 device (first one when empty) "
          "or .oni recording (paced at its recorded times, looped)"};
}

}  // namespace fb
