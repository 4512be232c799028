#include "drivers/camera/freenect/freenect_camera.hpp"

#include <dlfcn.h>
#include <libfreenect.h>
#include <libfreenect_registration.h>
#include <sys/stat.h>
#include <sys/time.h>

#include <algorithm>
#include <atomic>
#include <charconv>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "drivers/camera/common/camera_uri.hpp"
#include "drivers/camera/common/device_json.hpp"
#include "drivers/camera/common/host_clock.hpp"

namespace fb {
namespace {

constexpr int kDepthBytes = kKinectWidth * kKinectHeight * 2;  // FREENECT_DEPTH_11BIT, unpacked
constexpr int kColorBytes = kKinectWidth * kKinectHeight * 3;  // FREENECT_VIDEO_RGB
static_assert(sizeof(Rgb8) == 3, "colour frames are copied byte for byte into Rgb8 pixels");

constexpr std::string_view kUsage =
    "freenect:N[,calib=device.json][,stall_ms=3000]  Kinect v1 number N via libfreenect "
    "(run under fakenect to play a dump)";

// ---------------------------------------------------------------------------------------------
// RAII for libfreenect's C handles.

struct ContextDeleter {
  void operator()(freenect_context* context) const { freenect_shutdown(context); }
};
struct DeviceDeleter {
  void operator()(freenect_device* device) const { freenect_close_device(device); }
};
using ContextPtr = std::unique_ptr<freenect_context, ContextDeleter>;
using DevicePtr = std::unique_ptr<freenect_device, DeviceDeleter>;

// ---------------------------------------------------------------------------------------------
// Which libfreenect is loaded. Everything the fakenect build lacks is looked up at run time:
// calling such a symbol directly kills the process under fakenect ("symbol lookup error").

template <class Fn>
Fn optional_symbol(const char* name) {
  return reinterpret_cast<Fn>(dlsym(RTLD_DEFAULT, name));
}

struct LoadedLibrary {
  std::string path;       // file libfreenect was loaded from, when the loader can tell
  bool fakenect = false;  // the dump player rather than the USB driver
};

LoadedLibrary loaded_library() {
  LoadedLibrary library;
  // dlsym rather than &freenect_init: in a non-PIE binary the latter may be the executable's PLT.
  if (void* init = dlsym(RTLD_DEFAULT, "freenect_init")) {
    Dl_info info{};
    if (dladdr(init, &info) != 0 && info.dli_fname != nullptr) library.path = info.dli_fname;
  }
  const bool path_says_fakenect = library.path.find("fakenect") != std::string::npos;
  // A fakenect library installed elsewhere still lacks the device enumeration of the real one.
  const bool lacks_usb_symbols = dlsym(RTLD_DEFAULT, "freenect_list_device_attributes") == nullptr;
  library.fakenect = path_says_fakenect || lacks_usb_symbols;
  return library;
}

// ---------------------------------------------------------------------------------------------
// fakenect dumps. Debian's fakenect (0.5.3) reads $FAKENECT_PATH/INDEX.txt one line per
// freenect_process_events() call and calls exit(1) when INDEX.txt or a listed file cannot be
// opened or a PGM/PPM header has no newline; it reads past the end of a short frame file. It stops
// (returns -1 after printing "Warning: No more lines") at the end of INDEX.txt or at the first
// empty line. So the dump is checked here first, with the same reading rules, and a bad dump is a
// clear error instead of a silent exit of the whole process.

struct FakenectDump {
  std::string dir;
  long long depth_frames = 0;
  long long color_frames = 0;
};

bool is_regular_file(const std::string& path) {
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode);
}

bool is_directory(const std::string& path) {
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode);
}

// Checks that a PGM/PPM frame file has a one-line header followed by at least `payload` bytes.
Result<void> check_frame_file(const std::string& path, long long payload) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return fail("cannot read '" + path + "'");
  char header[64] = {};
  in.read(header, sizeof(header));
  const auto got = in.gcount();
  const char* newline =
      static_cast<const char*>(std::memchr(header, '\n', static_cast<size_t>(got)));
  if (newline == nullptr) return fail("'" + path + "' has no one-line PGM/PPM header");
  const long long header_bytes = newline - header + 1;
  in.clear();
  in.seekg(0, std::ios::end);
  const long long size = static_cast<long long>(in.tellg());
  if (size - header_bytes < payload) {
    return fail("'" + path + "' holds " + std::to_string(size - header_bytes) +
                " bytes of pixels, a 640x480 frame needs " + std::to_string(payload));
  }
  return success();
}

Result<FakenectDump> check_fakenect_dump(const LoadedLibrary& library) {
  const char* env = std::getenv("FAKENECT_PATH");
  const std::string running = "running under fakenect (" + library.path + ")";
  if (env == nullptr || *env == '\0') {
    return fail(running +
                " but FAKENECT_PATH is not set: set it to a dump directory recorded with "
                "fakenect's `record` (or run through /usr/bin/fakenect DIR ...)");
  }
  FakenectDump dump;
  dump.dir = env;
  if (!is_directory(dump.dir)) {
    return fail(running + ": FAKENECT_PATH='" + dump.dir + "' is not a directory");
  }
  const std::string index_path = dump.dir + "/INDEX.txt";
  std::ifstream index(index_path, std::ios::binary);
  if (!index) {
    return fail(running + ": '" + index_path +
                "' is missing or unreadable; FAKENECT_PATH must be a dump directory recorded "
                "with fakenect's `record`");
  }
  std::string line;
  int line_number = 0;
  while (std::getline(index, line)) {
    ++line_number;
    if (line.empty()) break;  // fakenect ends playback at the first empty line
    const std::string where =
        index_path + " line " + std::to_string(line_number) + " ('" + line + "')";
    char type = 0;
    double host_time = 0.0;
    unsigned timestamp = 0;
    // The file-name pattern fakenect parses; without it fakenect would sleep for an
    // uninitialised interval.
    if (std::sscanf(line.c_str(), "%c-%lf-%u-", &type, &host_time, &timestamp) != 3) {
      return fail(running + ": " + where + " is not a fakenect entry like d-TIME-TIMESTAMP.pgm");
    }
    const std::string file = dump.dir + "/" + line;
    if (!is_regular_file(file)) {
      return fail(running + ": " + where + " names a file that does not exist in the dump " +
                  "(fakenect would exit(1) on it)");
    }
    Result<void> checked = success();
    if (type == 'd') {
      checked = check_frame_file(file, kDepthBytes);
      ++dump.depth_frames;
    } else if (type == 'r') {
      checked = check_frame_file(file, kColorBytes);
      ++dump.color_frames;
    } else {
      struct stat st {};
      if (::stat(file.c_str(), &st) != 0 || st.st_size == 0)
        checked = fail("'" + file + "' is empty");
    }
    if (!checked) return fail(running + ": " + where + ": " + checked.error().message);
  }
  if (dump.depth_frames == 0) {
    return fail(running + ": '" + index_path + "' lists no depth frames (d-*.pgm)");
  }
  return dump;
}

// ---------------------------------------------------------------------------------------------
// Calibration sources.

KinectCalibration calibration_from(const freenect_registration& reg) {
  KinectCalibration c;
  const freenect_reg_info& r = reg.reg_info;
  c.reg_info = {r.ax,
                r.bx,
                r.cx,
                r.dx,
                r.ay,
                r.by,
                r.cy,
                r.dy,
                r.dx_start,
                r.dy_start,
                r.dx_beta_start,
                r.dy_beta_start,
                r.dx_beta_inc,
                r.dy_beta_inc,
                r.dxdx_start,
                r.dxdy_start,
                r.dydx_start,
                r.dydy_start,
                r.dxdxdx_start,
                r.dydxdx_start,
                r.dxdxdy_start,
                r.dydxdy_start,
                r.dydydx_start,
                r.dydydy_start};
  c.pad_info.start_lines = reg.reg_pad_info.start_lines;
  c.pad_info.end_lines = reg.reg_pad_info.end_lines;
  c.pad_info.cropping_lines = reg.reg_pad_info.cropping_lines;
  c.zero_plane_info.dcmos_emitter_distance = reg.zero_plane_info.dcmos_emitter_dist;
  c.zero_plane_info.dcmos_rcmos_distance = reg.zero_plane_info.dcmos_rcmos_dist;
  c.zero_plane_info.reference_distance = reg.zero_plane_info.reference_distance;
  c.zero_plane_info.reference_pixel_size = reg.zero_plane_info.reference_pixel_size;
  c.const_shift = static_cast<std::int32_t>(reg.const_shift + 0.5);
  return c;
}

// The registration libfreenect read from the device at open time, if this libfreenect can give
// it (fakenect cannot) and it looks like a real one.
std::optional<KinectCalibration> device_calibration(freenect_device* device) {
  using CopyFn = decltype(&freenect_copy_registration);
  using DestroyFn = decltype(&freenect_destroy_registration);
  const auto copy = optional_symbol<CopyFn>("freenect_copy_registration");
  const auto destroy = optional_symbol<DestroyFn>("freenect_destroy_registration");
  if (copy == nullptr || destroy == nullptr) return std::nullopt;
  freenect_registration reg = copy(device);
  std::optional<KinectCalibration> result;
  if (reg.zero_plane_info.reference_distance > 0.0f &&
      reg.zero_plane_info.reference_pixel_size > 0.0f) {
    result = calibration_from(reg);
  }
  destroy(&reg);
  return result;
}

// ---------------------------------------------------------------------------------------------
// URI options.

struct Options {
  int index = 0;
  std::string calib_path;
  std::chrono::milliseconds stall{3000};
};

Result<Options> parse_options(std::string_view arguments) {
  Options options;
  const auto comma = arguments.find(',');
  std::string_view first = arguments.substr(0, comma);
  std::string_view rest =
      comma == std::string_view::npos ? std::string_view{} : arguments.substr(comma + 1);
  if (first.find('=') != std::string_view::npos) {  // `freenect:calib=...`: device 0
    rest = arguments;
    first = {};
  }
  if (!first.empty()) {
    const auto [end, ec] =
        std::from_chars(first.data(), first.data() + first.size(), options.index);
    if (ec != std::errc{} || end != first.data() + first.size() || options.index < 0) {
      return fail("freenect: device index '" + std::string(first) +
                  "' is not a number; use e.g. 'freenect:0' (see `facebooth camera list`)");
    }
  }
  auto values = parse_key_values(rest);
  if (!values) return fail("freenect: " + values.error().message);
  for (const auto& [key, value] : *values) {
    if (key == "calib") {
      options.calib_path = value;
    } else if (key == "stall_ms") {
      long long ms = 0;
      const auto [end, ec] = std::from_chars(value.data(), value.data() + value.size(), ms);
      if (ec != std::errc{} || end != value.data() + value.size() || ms <= 0) {
        return fail("freenect: stall_ms='" + value + "' is not a positive number of milliseconds");
      }
      options.stall = std::chrono::milliseconds(ms);
    } else {
      return fail("freenect: unknown option '" + key + "'; known: calib=PATH, stall_ms=MS");
    }
  }
  return options;
}


Result<ContextPtr> init_context() {
  freenect_context* raw = nullptr;
  const int rc = freenect_init(&raw, nullptr);
  if (rc < 0 || raw == nullptr) {
    return fail("freenect: libfreenect could not initialise libusb (error " + std::to_string(rc) +
                "); is USB available to this process?");
  }
  ContextPtr context(raw);
  // Camera only: the motor and audio interfaces are not needed, and audio on model 1473 needs
  // firmware upload.
  freenect_select_subdevices(context.get(), FREENECT_DEVICE_CAMERA);
  return context;
}

std::string no_kinect_message() {
  return "freenect: no Kinect found on USB: check the cable/power/udev rules, or run under "
         "fakenect (LD_LIBRARY_PATH=/usr/lib/x86_64-linux-gnu/fakenect FAKENECT_PATH=DUMP_DIR, "
         "or `fakenect DUMP_DIR facebooth ...`) to play a recording";
}

// Serial numbers in enumeration order; empty when this libfreenect cannot enumerate (fakenect).
std::vector<std::string> device_serials(freenect_context* context) {
  using ListFn = decltype(&freenect_list_device_attributes);
  using FreeFn = decltype(&freenect_free_device_attributes);
  const auto list = optional_symbol<ListFn>("freenect_list_device_attributes");
  const auto free_list = optional_symbol<FreeFn>("freenect_free_device_attributes");
  std::vector<std::string> serials;
  if (list == nullptr || free_list == nullptr) return serials;
  freenect_device_attributes* head = nullptr;
  if (list(context, &head) < 0) return serials;
  std::unique_ptr<freenect_device_attributes, FreeFn> owned(head, free_list);
  for (auto* a = head; a != nullptr; a = a->next) {
    serials.emplace_back(a->camera_serial != nullptr ? a->camera_serial : "");
  }
  return serials;
}

// ---------------------------------------------------------------------------------------------

class FreenectCamera final : public DepthCamera {
 public:
  static Result<std::unique_ptr<DepthCamera>> open(std::string_view arguments);
  ~FreenectCamera() override { stop(); }

  const CameraInfo& info() const override { return info_; }
  Result<void> start() override;
  void stop() override;
  Result<FrameStatus> next_frame(RgbdFrame& frame, std::chrono::milliseconds timeout) override;

 private:
  FreenectCamera(ContextPtr context, DevicePtr device, const KinectCalibration& calibration)
      : registration_(calibration), context_(std::move(context)), device_(std::move(device)) {}

  static void on_depth(freenect_device* device, void* data, std::uint32_t timestamp);
  static void on_video(freenect_device* device, void* data, std::uint32_t timestamp);
  void event_loop();

  CameraInfo info_;
  KinectRegistration registration_;
  std::optional<FakenectDump> dump_;  // set when playing a dump under fakenect
  std::chrono::milliseconds stall_limit_{3000};

  // Declared in this order so the device closes before the context shuts down.
  ContextPtr context_;
  DevicePtr device_;

  std::thread events_;
  std::atomic<bool> stop_events_{false};
  bool streaming_ = false;  // only touched by the caller's thread

  // Double buffers: the callbacks (event thread) copy into the pending images under mu_;
  // next_frame() swaps a pending image with its own (no allocation, no copy under the lock) and
  // converts outside the lock. On a live device, a pending depth frame that is overwritten
  // before it was taken is dropped; the stream index in RgbdFrame::index shows the gap. A dump
  // played through fakenect loses nothing: its callback waits until the consumer took the
  // previous frame (a late first next_frame() on a loaded machine shifted every frame by one).
  // Colour has a third buffer: each depth frame latches the latest colour image that arrived
  // before it, so a slow consumer does not pair depth with a later colour image (the same
  // pairing as the replay backend: the last colour entry before the depth entry).
  std::mutex mu_;
  std::condition_variable arrived_;
  std::condition_variable taken_;  // dump playback: the consumer took the pending depth frame
  DisparityImage pending_depth_;
  ColorImage pending_color_;  // newest colour image from the device
  ColorImage latched_color_;  // the colour image belonging to pending_depth_
  bool depth_ready_ = false;
  bool color_ready_ = false;    // pending_color_ is newer than latched_color_
  bool latched_ready_ = false;  // latched_color_ is newer than the consumer's color_
  bool color_seen_ = false;
  std::uint64_t depth_sequence_ = 0;  // depth callbacks so far
  std::uint64_t pending_index_ = 0;
  std::uint32_t pending_depth_timestamp_ = 0;
  std::uint32_t pending_color_timestamp_ = 0;
  double pending_depth_time_ = 0.0;
  double pending_color_time_ = 0.0;
  std::uint32_t latched_color_timestamp_ = 0;
  double latched_color_time_ = 0.0;
  const HostClock host_clock_;  // frame host times (wall-like, never jumping)
  bool events_ended_ = false;
  int events_rc_ = 0;

  // Consumer side, only touched by the caller's thread.
  DisparityImage depth_;
  ColorImage color_;
  std::uint32_t color_timestamp_ = 0;
  double color_time_ = 0.0;
  std::chrono::steady_clock::time_point last_progress_{};
};

Result<std::unique_ptr<DepthCamera>> FreenectCamera::open(std::string_view arguments) {
  auto options = parse_options(arguments);
  if (!options) return options.failure();
  const std::string uri = "freenect:" + std::string(arguments);

  const LoadedLibrary library = loaded_library();
  std::optional<FakenectDump> dump;
  if (library.fakenect) {
    auto checked = check_fakenect_dump(library);
    if (!checked) return checked.failure();
    dump = std::move(*checked);
  }

  auto context = init_context();
  if (!context) return context.failure();
  const int count = freenect_num_devices(context->get());
  if (count < 0) {
    return fail("freenect: could not enumerate USB devices (libusb error " + std::to_string(count) +
                ")");
  }
  if (count == 0) return fail(no_kinect_message());
  if (options->index >= count) {
    return fail("freenect: device index " + std::to_string(options->index) +
                " is out of range: " + std::to_string(count) + " Kinect(s) found, use freenect:0" +
                (count > 1 ? "..freenect:" + std::to_string(count - 1) : std::string()));
  }
  const std::vector<std::string> serials = device_serials(context->get());

  freenect_device* raw_device = nullptr;
  if (freenect_open_device(context->get(), &raw_device, options->index) < 0 ||
      raw_device == nullptr) {
    return fail("freenect: could not open Kinect #" + std::to_string(options->index) +
                ": it is in use by another program, or this user may not access it (install "
                "the udev rules from board/, or check `lsusb` for 045e:02ae or 045e:02bf)");
  }
  DevicePtr device(raw_device);

  // Calibration: explicit file, then the dump's own device.json, then the device, then defaults.
  KinectCalibration calibration = KinectCalibration::typical_unit();
  std::string calibration_source = "defaults for a typical unit";
  if (!options->calib_path.empty()) {
    auto loaded = read_device_json(options->calib_path);
    if (!loaded)
      return fail("freenect: calib=" + options->calib_path + ": " + loaded.error().message);
    calibration = *loaded;
    calibration_source = options->calib_path;
  } else if (dump && is_regular_file(dump->dir + "/device.json")) {
    const std::string path = dump->dir + "/device.json";
    auto loaded = read_device_json(path);
    if (!loaded) return fail("freenect: " + path + ": " + loaded.error().message);
    calibration = *loaded;
    calibration_source = path;
  } else if (auto from_device = device_calibration(device.get())) {
    calibration = *from_device;
    calibration_source = "the device";
  }

  const freenect_frame_mode depth_mode =
      freenect_find_depth_mode(FREENECT_RESOLUTION_MEDIUM, FREENECT_DEPTH_11BIT);
  const freenect_frame_mode video_mode =
      freenect_find_video_mode(FREENECT_RESOLUTION_MEDIUM, FREENECT_VIDEO_RGB);
  if (!depth_mode.is_valid || !video_mode.is_valid || depth_mode.bytes != kDepthBytes ||
      video_mode.bytes != kColorBytes) {
    return fail("freenect: this libfreenect offers no 640x480 11-bit depth / RGB mode");
  }
  if (freenect_set_depth_mode(device.get(), depth_mode) < 0 ||
      freenect_set_video_mode(device.get(), video_mode) < 0) {
    return fail("freenect: Kinect #" + std::to_string(options->index) +
                " refused the 640x480 11-bit depth / RGB modes");
  }

  std::unique_ptr<FreenectCamera> camera(
      new FreenectCamera(std::move(*context), std::move(device), calibration));
  camera->stall_limit_ = options->stall;
  camera->dump_ = dump;
  // All buffers are sized here so that streaming never allocates.
  camera->pending_depth_.resize(kKinectWidth, kKinectHeight);
  camera->depth_.resize(kKinectWidth, kKinectHeight);
  camera->pending_color_.resize(kKinectWidth, kKinectHeight);
  camera->latched_color_.resize(kKinectWidth, kKinectHeight);
  camera->color_.resize(kKinectWidth, kKinectHeight);

  CameraInfo& info = camera->info_;
  info.uri = uri;
  info.backend = "freenect";
  if (dump) {
    info.description = "fakenect dump " + dump->dir + " (" + std::to_string(dump->depth_frames) +
                       " depth frames), calibration from " + calibration_source;
    info.frame_count = dump->depth_frames;
  } else {
    const std::string serial = static_cast<std::size_t>(options->index) < serials.size()
                                   ? serials[static_cast<std::size_t>(options->index)]
                                   : std::string("?");
    info.description = "Kinect v1 #" + std::to_string(options->index) + " serial " + serial +
                       ", calibration from " + calibration_source;
  }
  info.calibration = calibration;
  info.depth_intrinsics = calibration.depth_intrinsics();

  freenect_set_depth_callback(camera->device_.get(), &FreenectCamera::on_depth);
  freenect_set_video_callback(camera->device_.get(), &FreenectCamera::on_video);
  return std::unique_ptr<DepthCamera>(std::move(camera));
}

void FreenectCamera::on_depth(freenect_device* device, void* data, std::uint32_t timestamp) {
  auto* self = static_cast<FreenectCamera*>(freenect_get_user(device));
  const double now = self->host_clock_.now_s();
  {
    std::unique_lock lock(self->mu_);
    // A looping fakenect (upstream >= 0.5.7 restarts INDEX.txt by default) would replay the
    // dump forever; the dump ends after the depth frames its INDEX.txt lists.
    if (self->dump_ && static_cast<long long>(self->depth_sequence_) >= self->dump_->depth_frames) {
      return;
    }
    if (self->dump_) {
      // Polls the stop flag: stop() joins this (event) thread.
      while (self->depth_ready_ && !self->stop_events_.load(std::memory_order_relaxed)) {
        self->taken_.wait_for(lock, std::chrono::milliseconds(20));
      }
    }
    std::memcpy(self->pending_depth_.pixels.data(), data, kDepthBytes);
    self->pending_index_ = self->depth_sequence_++;
    self->pending_depth_timestamp_ = timestamp;
    self->pending_depth_time_ = now;
    self->depth_ready_ = true;
    if (self->color_ready_) {
      std::swap(self->latched_color_.pixels, self->pending_color_.pixels);
      self->latched_color_timestamp_ = self->pending_color_timestamp_;
      self->latched_color_time_ = self->pending_color_time_;
      self->color_ready_ = false;
      self->latched_ready_ = true;
    }
  }
  self->arrived_.notify_one();
}

void FreenectCamera::on_video(freenect_device* device, void* data, std::uint32_t timestamp) {
  auto* self = static_cast<FreenectCamera*>(freenect_get_user(device));
  const double now = self->host_clock_.now_s();
  std::lock_guard lock(self->mu_);
  std::memcpy(self->pending_color_.pixels.data(), data, kColorBytes);
  self->pending_color_timestamp_ = timestamp;
  self->pending_color_time_ = now;
  self->color_ready_ = true;
}

void FreenectCamera::event_loop() {
  while (!stop_events_.load(std::memory_order_relaxed)) {
    // A short libusb timeout bounds how long stop() waits on a live device. fakenect ignores it
    // and sleeps up to one recorded inter-frame gap per call instead.
    timeval timeout{0, 100'000};
    const int rc = freenect_process_events_timeout(context_.get(), &timeout);
    if (rc < 0) {
      {
        std::lock_guard lock(mu_);
        events_ended_ = true;
        events_rc_ = rc;
      }
      arrived_.notify_all();
      return;
    }
  }
}

Result<void> FreenectCamera::start() {
  if (streaming_) return success();
  {
    std::lock_guard lock(mu_);
    if (events_ended_) {
      return fail(dump_ ? "freenect: the fakenect dump " + dump_->dir +
                              " has ended; fakenect plays a dump once per process"
                        : "freenect: the Kinect stopped with libusb error " +
                              std::to_string(events_rc_) + "; reopen it");
    }
  }
  // Set here rather than at open: fakenect has one global user pointer for all "devices", and
  // the camera that streams must be the one that receives the callbacks.
  freenect_set_user(device_.get(), this);
  if (freenect_start_depth(device_.get()) < 0) {
    return fail("freenect: could not start the depth stream of " + info_.description +
                " (unplugged, or not enough USB bandwidth: use a USB 2.0 port of its own)");
  }
  if (freenect_start_video(device_.get()) < 0) {
    freenect_stop_depth(device_.get());
    return fail("freenect: could not start the colour stream of " + info_.description +
                " (not enough USB bandwidth: use a USB 2.0 port of its own)");
  }
  stop_events_.store(false);
  events_ = std::thread([this] { event_loop(); });
  streaming_ = true;
  last_progress_ = std::chrono::steady_clock::now();
  return success();
}

void FreenectCamera::stop() {
  if (!streaming_) return;
  stop_events_.store(true);
  if (events_.joinable()) events_.join();
  // Stopping the streams processes libusb events itself, so it must not race the event thread.
  freenect_stop_video(device_.get());
  freenect_stop_depth(device_.get());
  streaming_ = false;
}

Result<FrameStatus> FreenectCamera::next_frame(RgbdFrame& frame,
                                               std::chrono::milliseconds timeout) {
  if (!streaming_) return fail("freenect: next_frame() called before start()");
  std::unique_lock lock(mu_);
  const auto dump_done = [this] {
    return dump_ && static_cast<long long>(depth_sequence_) >= dump_->depth_frames;
  };
  arrived_.wait_for(lock, timeout, [&] { return depth_ready_ || events_ended_ || dump_done(); });
  const auto now = std::chrono::steady_clock::now();
  if (!depth_ready_) {
    if (dump_done()) return FrameStatus::kEndOfStream;
    if (events_ended_) {
      if (!dump_) {
        return fail("freenect: " + info_.description + " stopped streaming (libusb error " +
                    std::to_string(events_rc_) + "): was it unplugged?");
      }
      // Debian's fakenect returns -1 at the end of INDEX.txt; all depth frames arrived or
      // dump_done() would have said so. Fewer frames mean fakenect resumed an index that an
      // earlier camera in this process had (partly) played.
      return fail("freenect: fakenect ended after " + std::to_string(depth_sequence_) + " of the " +
                  std::to_string(dump_->depth_frames) + " depth frames listed in " + dump_->dir +
                  "/INDEX.txt. Debian's fakenect keeps its INDEX.txt position across "
                  "freenect_shutdown(), so a dump plays only once per process");
    }
    if (now - last_progress_ > stall_limit_) {
      return fail(
          "freenect: no frames from " + info_.description + " for " +
          std::to_string(
              std::chrono::duration_cast<std::chrono::milliseconds>(now - last_progress_).count()) +
          " ms: the Kinect was unplugged or stalled (check power and USB)");
    }
    return FrameStatus::kTimeout;
  }

  std::swap(depth_.pixels, pending_depth_.pixels);
  depth_ready_ = false;
  taken_.notify_one();
  frame.index = pending_index_;
  frame.depth_device_timestamp = pending_depth_timestamp_;
  frame.depth_host_time_s = pending_depth_time_;
  const bool new_color = latched_ready_;
  if (new_color) {
    std::swap(color_.pixels, latched_color_.pixels);
    latched_ready_ = false;
    color_timestamp_ = latched_color_timestamp_;
    color_time_ = latched_color_time_;
  }
  lock.unlock();

  last_progress_ = now;
  color_seen_ = color_seen_ || new_color;
  frame.color_device_timestamp = color_timestamp_;
  frame.color_host_time_s = color_time_;
  frame.raw_disparity.resize(kKinectWidth, kKinectHeight);
  std::copy(depth_.pixels.begin(), depth_.pixels.end(), frame.raw_disparity.pixels.begin());
  registration_.disparity_to_mm(depth_, frame.depth_mm);
  frame.color.resize(kKinectWidth, kKinectHeight);
  if (color_seen_) {
    std::copy(color_.pixels.begin(), color_.pixels.end(), frame.color.pixels.begin());
  } else {
    std::fill(frame.color.pixels.begin(), frame.color.pixels.end(), Rgb8{});  // none yet
  }
  return FrameStatus::kFrame;
}

Result<std::unique_ptr<DepthCamera>> open_freenect(std::string_view arguments) {
  return FreenectCamera::open(arguments);
}

std::vector<CameraListing> list_freenect() {
  std::vector<CameraListing> listed;
  const LoadedLibrary library = loaded_library();
  if (library.fakenect) {
    // fakenect always reports one device; only list it when it has a dump to play.
    auto dump = check_fakenect_dump(library);
    if (dump) {
      listed.push_back({"freenect:0", "fakenect dump " + dump->dir + " (" +
                                          std::to_string(dump->depth_frames) + " depth frames)"});
    }
    return listed;
  }
  auto context = init_context();
  if (!context) return listed;
  const int count = freenect_num_devices(context->get());
  const std::vector<std::string> serials = device_serials(context->get());
  for (int i = 0; i < count; ++i) {
    const auto n = static_cast<std::size_t>(i);
    listed.push_back({"freenect:" + std::to_string(i),
                      "Kinect v1 serial " + (n < serials.size() ? serials[n] : std::string("?"))});
  }
  return listed;
}

}  // namespace

CameraBackend freenect_camera_backend() {
  return {"freenect", &open_freenect, &list_freenect, kUsage};
}

}  // namespace fb
