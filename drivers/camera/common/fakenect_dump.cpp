#include "drivers/camera/common/fakenect_dump.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <system_error>
#include <utility>

#include "drivers/camera/common/device_json.hpp"

namespace fb {
namespace {

constexpr std::size_t kNone = std::numeric_limits<std::size_t>::max();
constexpr int kMaxImageSide = 8192;  // sanity bound so a corrupt header cannot ask for GBs

std::string errno_text(int err) {
  return std::error_code(err, std::generic_category()).message();
}

// Owns a POSIX file descriptor. POSIX I/O rather than FILE*: no stdio buffer allocation per file,
// and whole-buffer read()/write() calls.
class UniqueFd {
 public:
  UniqueFd() = default;
  explicit UniqueFd(int fd) : fd_(fd) {}
  UniqueFd(UniqueFd&& other) noexcept : fd_(std::exchange(other.fd_, -1)) {}
  UniqueFd& operator=(UniqueFd&& other) noexcept {
    if (this != &other) {
      reset();
      fd_ = std::exchange(other.fd_, -1);
    }
    return *this;
  }
  UniqueFd(const UniqueFd&) = delete;
  UniqueFd& operator=(const UniqueFd&) = delete;
  ~UniqueFd() { reset(); }

  int get() const { return fd_; }
  bool valid() const { return fd_ >= 0; }
  void reset() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }
  // Closes and reports the error close() returns (delayed write errors show up here).
  int close_checked() {
    if (fd_ < 0) return 0;
    const int rc = ::close(std::exchange(fd_, -1));
    return rc == 0 ? 0 : errno;
  }

 private:
  int fd_ = -1;
};

// Reads a whole file into `out` (resized; capacity reused).
Result<void> read_file(const std::string& path, std::vector<std::uint8_t>& out) {
  UniqueFd fd(::open(path.c_str(), O_RDONLY | O_CLOEXEC));
  if (!fd.valid()) {
    const int err = errno;
    return fail("cannot open '" + path + "': " + errno_text(err) +
                (err == ENOENT ? " (the dump is incomplete; re-copy or re-record it)" : ""));
  }
  struct stat st {};
  if (::fstat(fd.get(), &st) != 0) {
    const int err = errno;
    return fail("cannot stat '" + path + "': " + errno_text(err));
  }
  out.resize(static_cast<std::size_t>(st.st_size));
  std::size_t done = 0;
  while (done < out.size()) {
    const ssize_t n = ::read(fd.get(), out.data() + done, out.size() - done);
    if (n < 0) {
      const int err = errno;
      if (err == EINTR) continue;
      return fail("error reading '" + path + "': " + errno_text(err));
    }
    if (n == 0) break;  // file shrank while reading
    done += static_cast<std::size_t>(n);
  }
  out.resize(done);
  return success();
}

Result<void> write_all(int fd, const void* data, std::size_t size, const std::string& what) {
  const auto* p = static_cast<const std::uint8_t*>(data);
  while (size > 0) {
    const ssize_t n = ::write(fd, p, size);
    if (n < 0) {
      const int err = errno;
      if (err == EINTR) continue;
      return fail("error writing '" + what + "': " + errno_text(err) +
                  (err == ENOSPC ? " (disk full; the dump so far is still valid)" : ""));
    }
    p += n;
    size -= static_cast<std::size_t>(n);
  }
  return success();
}

struct PnmHeader {
  int width = 0;
  int height = 0;
  int maxval = 0;
  std::size_t data_offset = 0;
};

// Parses "P5|P6 <ws> width <ws> height <ws> maxval <one ws>" with '#' comments, as netpbm does.
Result<PnmHeader> parse_pnm_header(const std::vector<std::uint8_t>& bytes, char kind,
                                   const std::string& path) {
  const std::string expected = std::string("P") + kind;
  if (bytes.size() < 2 || bytes[0] != 'P' || bytes[1] != static_cast<std::uint8_t>(kind)) {
    if (bytes.empty()) return fail("'" + path + "' is empty (truncated recording?)");
    return fail("'" + path + "' is not a binary " + (kind == '5' ? "PGM" : "PPM") +
                " file (expected magic '" + expected + "')");
  }
  std::size_t pos = 2;
  int values[3] = {0, 0, 0};
  const char* names[3] = {"width", "height", "maxval"};
  for (int k = 0; k < 3; ++k) {
    // Skip whitespace and comments.
    while (pos < bytes.size()) {
      const char c = static_cast<char>(bytes[pos]);
      if (c == '#') {
        while (pos < bytes.size() && bytes[pos] != '\n') ++pos;
      } else if (c == ' ' || c == '\t' || c == '\n' || c == '\r') {
        ++pos;
      } else {
        break;
      }
    }
    const auto* begin = reinterpret_cast<const char*>(bytes.data()) + pos;
    const auto* end = reinterpret_cast<const char*>(bytes.data()) + bytes.size();
    const auto [ptr, ec] = std::from_chars(begin, end, values[k]);
    if (ec != std::errc() || ptr == begin) {
      return fail("'" + path + "' has a malformed " + expected + " header: cannot read the " +
                  names[k] + " (truncated or not a fakenect file)");
    }
    pos += static_cast<std::size_t>(ptr - begin);
  }
  if (pos >= bytes.size() || !std::isspace(bytes[pos])) {
    return fail("'" + path + "' has a malformed " + expected +
                " header: no whitespace after the maxval (truncated?)");
  }
  ++pos;  // exactly one whitespace byte separates the header from the pixels
  PnmHeader h{values[0], values[1], values[2], pos};
  if (h.width <= 0 || h.height <= 0 || h.width > kMaxImageSide || h.height > kMaxImageSide) {
    return fail("'" + path + "' has an implausible size " + std::to_string(h.width) + "x" +
                std::to_string(h.height));
  }
  return h;
}

Result<void> check_payload(const std::vector<std::uint8_t>& bytes, const PnmHeader& h,
                           std::size_t bytes_per_pixel, const std::string& path) {
  const std::size_t need = static_cast<std::size_t>(h.width) * h.height * bytes_per_pixel;
  const std::size_t have = bytes.size() - h.data_offset;
  if (have < need) {
    return fail("'" + path + "' is truncated: " + std::to_string(have) +
                " bytes of pixel data for " + std::to_string(h.width) + "x" +
                std::to_string(h.height) + ", expected " + std::to_string(need) +
                " (interrupted copy or recording; re-copy the dump)");
  }
  if (have > need) {
    return fail("'" + path + "' has " + std::to_string(have - need) +
                " bytes after the pixel data; the header size " + std::to_string(h.width) + "x" +
                std::to_string(h.height) + " does not match the file");
  }
  return success();
}

std::size_t type_slot(DumpEntryType t) {
  switch (t) {
    case DumpEntryType::kDepth:
      return 0;
    case DumpEntryType::kColor:
      return 1;
    case DumpEntryType::kAccel:
      return 2;
  }
  return 0;
}

const char* extension_of(DumpEntryType t) {
  switch (t) {
    case DumpEntryType::kDepth:
      return "pgm";
    case DumpEntryType::kColor:
      return "ppm";
    case DumpEntryType::kAccel:
      return "dump";
  }
  return "";
}

void format_name_us(DumpEntryType type, long long micros, std::uint32_t ts, std::string& out) {
  char buf[96];
  const int n = std::snprintf(buf, sizeof buf, "%c-%lld.%06lld-%u.%s", static_cast<char>(type),
                              micros / 1000000, micros % 1000000, static_cast<unsigned>(ts),
                              extension_of(type));
  out.assign(buf, static_cast<std::size_t>(n));
}

// Host times past this (the year 33658) are not clock readings; their microseconds would not
// fit a long long either, so names with them are refused and the writer clamps to it.
constexpr double kMaxHostTimeS = 1e12;

long long to_micros(double host_time_s) {
  if (!(host_time_s > 0.0)) return 0;  // also catches NaN
  return std::llround(std::min(host_time_s, kMaxHostTimeS) * 1e6);
}

bool is_dump_file_name(const std::string& name) {
  return name == kDumpIndexFileName || name == kDumpDeviceJsonFileName ||
         parse_dump_file_name(name).ok();
}

}  // namespace

Result<DumpEntry> parse_dump_file_name(std::string_view name) {
  const auto bad = [&](const char* why) {
    return fail("'" + std::string(name) + "' is not a fakenect dump file name (" + why +
                "; expected e.g. d-1513096835.219278-2320228015.pgm)");
  };
  if (name.size() < 7 || name[1] != '-') return bad("wrong shape");
  DumpEntry e;
  switch (name[0]) {
    case 'd':
      e.type = DumpEntryType::kDepth;
      break;
    case 'r':
      e.type = DumpEntryType::kColor;
      break;
    case 'a':
      e.type = DumpEntryType::kAccel;
      break;
    default:
      return bad("type must be d, r or a");
  }
  const std::string_view rest = name.substr(2);
  const auto dash = rest.find('-');
  if (dash == std::string_view::npos) return bad("no '-' before the device timestamp");
  const std::string_view time_text = rest.substr(0, dash);
  const auto dot = rest.find('.', dash + 1);
  if (dot == std::string_view::npos) return bad("no extension");
  const std::string_view ts_text = rest.substr(dash + 1, dot - dash - 1);
  const std::string_view ext = rest.substr(dot + 1);

  // from_chars for double is available in GCC 11+; the host time is plain decimal.
  const auto [tp, tec] = std::from_chars(time_text.data(), time_text.data() + time_text.size(),
                                         e.host_time_s, std::chars_format::fixed);
  if (tec != std::errc() || tp != time_text.data() + time_text.size() || time_text.empty() ||
      time_text[0] == '-' || !std::isfinite(e.host_time_s)) {
    return bad("host time is not a number");
  }
  if (e.host_time_s > kMaxHostTimeS) return bad("host time is out of range");
  unsigned long long ts = 0;
  const auto [sp, sec] = std::from_chars(ts_text.data(), ts_text.data() + ts_text.size(), ts);
  if (sec != std::errc() || sp != ts_text.data() + ts_text.size() || ts_text.empty() ||
      ts > std::numeric_limits<std::uint32_t>::max()) {
    return bad("device timestamp is not a 32-bit unsigned number");
  }
  e.device_timestamp = static_cast<std::uint32_t>(ts);
  if (ext != extension_of(e.type)) return bad("extension does not match the type");
  e.file_name = std::string(name);
  return e;
}

void format_dump_file_name(DumpEntryType type, double host_time_s, std::uint32_t device_timestamp,
                           std::string& out) {
  format_name_us(type, to_micros(host_time_s), device_timestamp, out);
}

Result<void> read_depth_pgm(const std::string& path, DisparityImage& out,
                            std::vector<std::uint8_t>& scratch) {
  if (auto r = read_file(path, scratch); !r) return r;
  auto header = parse_pnm_header(scratch, '5', path);
  if (!header) return header.failure();
  const PnmHeader& h = *header;
  if (h.maxval != 65535 && h.maxval != 2047) {
    return fail("'" + path + "' has maxval " + std::to_string(h.maxval) +
                "; a Kinect depth PGM has 16-bit samples (maxval 65535) holding 11-bit disparity");
  }
  if (auto r = check_payload(scratch, h, 2, path); !r) return r;
  if (out.width != h.width || out.height != h.height ||
      out.pixels.size() != static_cast<std::size_t>(h.width) * h.height) {
    out.resize(h.width, h.height);
  }
  const std::uint8_t* p = scratch.data() + h.data_offset;
  const std::size_t n = out.pixels.size();
  // fakenect writes host order (little-endian). Decode that, and fall back to big-endian only if
  // the little-endian reading cannot be 11-bit data.
  std::uint16_t max_le = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const auto v = static_cast<std::uint16_t>(p[2 * i] | (p[2 * i + 1] << 8));
    out.pixels[i] = v;
    max_le = std::max(max_le, v);
  }
  if (max_le <= kInvalidDisparity) return success();
  std::uint16_t max_be = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const auto v = static_cast<std::uint16_t>((p[2 * i] << 8) | p[2 * i + 1]);
    out.pixels[i] = v;
    max_be = std::max(max_be, v);
  }
  if (max_be <= kInvalidDisparity) return success();
  return fail("'" + path + "' holds values above 2047 in either byte order; it is not 11-bit " +
              "Kinect disparity (was it recorded in a millimetre or registered depth mode?)");
}

Result<void> read_color_ppm(const std::string& path, ColorImage& out,
                            std::vector<std::uint8_t>& scratch) {
  if (auto r = read_file(path, scratch); !r) return r;
  auto header = parse_pnm_header(scratch, '6', path);
  if (!header) return header.failure();
  const PnmHeader& h = *header;
  if (h.maxval != 255) {
    return fail("'" + path + "' has maxval " + std::to_string(h.maxval) +
                "; a Kinect colour PPM has 8-bit samples (maxval 255)");
  }
  if (auto r = check_payload(scratch, h, 3, path); !r) return r;
  if (out.width != h.width || out.height != h.height ||
      out.pixels.size() != static_cast<std::size_t>(h.width) * h.height) {
    out.resize(h.width, h.height);
  }
  static_assert(sizeof(Rgb8) == 3, "Rgb8 must be packed RGB");
  std::memcpy(out.pixels.data(), scratch.data() + h.data_offset, out.pixels.size() * 3);
  return success();
}

Result<AccelSample> read_accel_dump(const std::string& path) {
  std::vector<std::uint8_t> scratch;
  return read_accel_dump(path, scratch);
}

Result<AccelSample> read_accel_dump(const std::string& path, std::vector<std::uint8_t>& bytes) {
  if (auto r = read_file(path, bytes); !r) return r.failure();
  if (bytes.size() != kAccelDumpSize) {
    return fail("'" + path + "' has " + std::to_string(bytes.size()) + " bytes; an accelerometer " +
                "dump (freenect_raw_tilt_state) has " + std::to_string(kAccelDumpSize));
  }
  const auto i16 = [&](int o) {
    return static_cast<std::int16_t>(static_cast<std::uint16_t>(bytes[o] | (bytes[o + 1] << 8)));
  };
  AccelSample s;
  s.accelerometer_x = i16(0);
  s.accelerometer_y = i16(2);
  s.accelerometer_z = i16(4);
  s.tilt_angle = static_cast<std::int8_t>(bytes[6]);
  s.tilt_status = static_cast<std::int32_t>(static_cast<std::uint32_t>(bytes[8]) |
                                            (static_cast<std::uint32_t>(bytes[9]) << 8) |
                                            (static_cast<std::uint32_t>(bytes[10]) << 16) |
                                            (static_cast<std::uint32_t>(bytes[11]) << 24));
  return s;
}

void encode_depth_pgm(const DisparityImage& raw, std::vector<std::uint8_t>& out) {
  char header[64];
  const int hn = std::snprintf(header, sizeof header, "P5 %d %d 65535\n", raw.width, raw.height);
  out.resize(static_cast<std::size_t>(hn) + raw.pixels.size() * 2);
  std::memcpy(out.data(), header, static_cast<std::size_t>(hn));
  std::uint8_t* p = out.data() + hn;
  for (std::size_t i = 0; i < raw.pixels.size(); ++i) {
    p[2 * i] = static_cast<std::uint8_t>(raw.pixels[i] & 0xff);
    p[2 * i + 1] = static_cast<std::uint8_t>(raw.pixels[i] >> 8);
  }
}

void encode_color_ppm(const ColorImage& rgb, std::vector<std::uint8_t>& out) {
  char header[64];
  const int hn = std::snprintf(header, sizeof header, "P6 %d %d 255\n", rgb.width, rgb.height);
  out.resize(static_cast<std::size_t>(hn) + rgb.pixels.size() * 3);
  std::memcpy(out.data(), header, static_cast<std::size_t>(hn));
  std::memcpy(out.data() + hn, rgb.pixels.data(), rgb.pixels.size() * 3);
}

void encode_accel_dump(const AccelSample& s, std::vector<std::uint8_t>& out) {
  out.assign(kAccelDumpSize, 0);
  const auto put16 = [&](int o, std::int16_t v) {
    const auto u = static_cast<std::uint16_t>(v);
    out[o] = static_cast<std::uint8_t>(u & 0xff);
    out[o + 1] = static_cast<std::uint8_t>(u >> 8);
  };
  put16(0, s.accelerometer_x);
  put16(2, s.accelerometer_y);
  put16(4, s.accelerometer_z);
  out[6] = static_cast<std::uint8_t>(s.tilt_angle);
  const auto st = static_cast<std::uint32_t>(s.tilt_status);
  for (int k = 0; k < 4; ++k) out[8 + k] = static_cast<std::uint8_t>(st >> (8 * k));
}

// ---------------------------------------------------------------------------------------------
// Reader

struct FakenectDumpReader::Impl {
  std::filesystem::path directory;
  std::vector<DumpEntry> entries;
  std::vector<std::string> paths;  // full path per entry, built once so next() does not allocate
  struct FrameRef {
    std::size_t depth = kNone;
    std::size_t color = kNone;
    std::size_t accel = kNone;
  };
  std::vector<FrameRef> frames;
  std::size_t color_images = 0;
  std::optional<KinectCalibration> calibration;

  std::size_t position = 0;
  std::vector<std::uint8_t> scratch;
  ColorImage color_cache;
  std::size_t cached_color = kNone;
  std::optional<AccelSample> accel;
  std::size_t cached_accel = kNone;
};

FakenectDumpReader::FakenectDumpReader(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
FakenectDumpReader::FakenectDumpReader(FakenectDumpReader&&) noexcept = default;
FakenectDumpReader& FakenectDumpReader::operator=(FakenectDumpReader&&) noexcept = default;
FakenectDumpReader::~FakenectDumpReader() = default;

Result<FakenectDumpReader> FakenectDumpReader::open(const std::filesystem::path& directory) {
  std::error_code ec;
  if (!std::filesystem::exists(directory, ec)) {
    return fail("fakenect dump directory '" + directory.string() +
                "' does not exist; pass the directory that contains INDEX.txt");
  }
  if (!std::filesystem::is_directory(directory, ec)) {
    return fail("'" + directory.string() +
                "' is not a directory; a fakenect dump is a directory with INDEX.txt and "
                "d-/r-/a- files (extract .tar.xz archives first)");
  }
  const auto index_path = directory / kDumpIndexFileName;
  std::ifstream index(index_path, std::ios::binary);
  if (!index) {
    return fail("'" + directory.string() + "' has no readable INDEX.txt; it is not a fakenect " +
                "dump (if it is an archive's parent, point at the extracted dump directory)");
  }
  auto impl = std::make_unique<Impl>();
  impl->directory = directory;

  std::string text((std::istreambuf_iterator<char>(index)), std::istreambuf_iterator<char>());
  if (index.bad()) return fail("error reading '" + index_path.string() + "'");
  std::size_t line_no = 0;
  std::size_t start = 0;
  while (start < text.size()) {
    const auto nl = text.find('\n', start);
    const bool terminated = nl != std::string::npos;
    std::string_view line(text.data() + start, (terminated ? nl : text.size()) - start);
    start = terminated ? nl + 1 : text.size();
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    if (line.empty()) continue;
    auto entry = parse_dump_file_name(line);
    if (!entry) {
      // An interrupted writer may leave a partial last line; everything before it is valid.
      if (!terminated) break;
      return fail(index_path.string() + " line " + std::to_string(line_no) + ": " +
                  entry.error().message);
    }
    if (line.find('/') != std::string_view::npos) {
      return fail(index_path.string() + " line " + std::to_string(line_no) +
                  ": file names must not contain '/'");
    }
    auto full = (directory / entry->file_name).string();
    if (!std::filesystem::is_regular_file(full, ec)) {
      return fail(index_path.string() + " line " + std::to_string(line_no) + " lists '" +
                  entry->file_name + "', but '" + full +
                  "' does not exist; the dump is incomplete (re-copy or re-extract it)");
    }
    impl->paths.push_back(std::move(full));
    impl->entries.push_back(std::move(*entry));
  }

  // Pair frames: latest colour/accel at or before each depth entry.
  std::size_t last_color = kNone;
  std::size_t first_color = kNone;
  std::size_t last_accel = kNone;
  for (std::size_t i = 0; i < impl->entries.size(); ++i) {
    switch (impl->entries[i].type) {
      case DumpEntryType::kColor:
        last_color = i;
        if (first_color == kNone) first_color = i;
        ++impl->color_images;
        break;
      case DumpEntryType::kAccel:
        last_accel = i;
        break;
      case DumpEntryType::kDepth:
        impl->frames.push_back({i, last_color, last_accel});
        break;
    }
  }
  for (auto& f : impl->frames) {
    if (f.color == kNone) f.color = first_color;  // depth before any colour: use the first one
  }

  const auto json_path = directory / kDumpDeviceJsonFileName;
  if (std::filesystem::exists(json_path, ec)) {
    auto calibration = read_device_json(json_path);
    if (!calibration) {
      return fail(calibration.error().message +
                  " (delete device.json to fall back to the default Kinect calibration)");
    }
    impl->calibration = *calibration;
  }
  // Buffers sized up front so the first frames do not allocate either.
  impl->scratch.reserve(640 * 480 * 3 + 64);
  return FakenectDumpReader(std::move(impl));
}

const std::filesystem::path& FakenectDumpReader::directory() const {
  return impl_->directory;
}
const std::vector<DumpEntry>& FakenectDumpReader::entries() const {
  return impl_->entries;
}
std::size_t FakenectDumpReader::depth_frame_count() const {
  return impl_->frames.size();
}
std::size_t FakenectDumpReader::color_image_count() const {
  return impl_->color_images;
}
const std::optional<KinectCalibration>& FakenectDumpReader::device_calibration() const {
  return impl_->calibration;
}
const std::optional<AccelSample>& FakenectDumpReader::accel() const {
  return impl_->accel;
}
std::size_t FakenectDumpReader::position() const {
  return impl_->position;
}
double FakenectDumpReader::depth_host_time(std::size_t i) const {
  return impl_->entries[impl_->frames.at(i).depth].host_time_s;
}
void FakenectDumpReader::rewind() {
  impl_->position = 0;
}

Result<bool> FakenectDumpReader::next(RgbdFrame& frame) {
  Impl& m = *impl_;
  if (m.position >= m.frames.size()) return false;
  const Impl::FrameRef& ref = m.frames[m.position];
  const DumpEntry& depth = m.entries[ref.depth];
  if (auto r = read_depth_pgm(m.paths[ref.depth], frame.raw_disparity, m.scratch); !r) {
    return r.failure();
  }
  frame.depth_host_time_s = depth.host_time_s;
  frame.depth_device_timestamp = depth.device_timestamp;
  if (ref.color != kNone) {
    if (m.cached_color != ref.color) {
      m.cached_color = kNone;  // stays invalid if the read fails
      if (auto r = read_color_ppm(m.paths[ref.color], m.color_cache, m.scratch); !r) {
        return r.failure();
      }
      m.cached_color = ref.color;
    }
    frame.color = m.color_cache;  // vector copy-assignment reuses the frame's capacity
    frame.color_host_time_s = m.entries[ref.color].host_time_s;
    frame.color_device_timestamp = m.entries[ref.color].device_timestamp;
  } else {
    frame.color.width = 0;
    frame.color.height = 0;
    frame.color.pixels.clear();  // keeps capacity
    frame.color_host_time_s = 0.0;
    frame.color_device_timestamp = 0;
  }
  if (ref.accel != kNone && ref.accel != m.cached_accel) {
    auto sample = read_accel_dump(m.paths[ref.accel], m.scratch);
    if (!sample) return sample.failure();
    m.accel = *sample;
    m.cached_accel = ref.accel;
  } else if (ref.accel == kNone) {
    m.accel.reset();
    m.cached_accel = kNone;
  }
  frame.index = m.position;
  ++m.position;
  return true;
}

// ---------------------------------------------------------------------------------------------
// Writer

struct FakenectDumpWriter::Impl {
  std::filesystem::path directory;
  std::string directory_string;
  std::string index_path;
  DumpWriterOptions options;
  UniqueFd index_fd;
  bool finished = false;

  std::vector<std::uint8_t> buffer;
  std::string name;
  std::string path;
  long long last_micros[3] = {-1, -1, -1};
  long long counts[3] = {0, 0, 0};

  Result<void> write_entry(DumpEntryType type, double host_time_s, std::uint32_t ts) {
    if (finished || !index_fd.valid()) {
      return fail("fakenect dump '" + directory_string +
                  "' is already finished; create a new writer");
    }
    const std::size_t slot = type_slot(type);
    long long micros = to_micros(host_time_s);
    if (micros <= last_micros[slot]) micros = last_micros[slot] + 1;
    format_name_us(type, micros, ts, name);
    path.assign(directory_string);
    path.push_back('/');
    path.append(name);

    {
      UniqueFd fd(::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644));
      if (!fd.valid()) {
        const int err = errno;
        return fail("cannot create '" + path + "': " + errno_text(err));
      }
      if (auto r = write_all(fd.get(), buffer.data(), buffer.size(), path); !r) return r;
      if (options.sync_each_entry && ::fsync(fd.get()) != 0) {
        return fail("fsync of '" + path + "' failed: " + errno_text(errno));
      }
      if (const int err = fd.close_checked(); err != 0) {
        return fail("error closing '" + path + "': " + errno_text(err));
      }
    }
    // Only now the entry becomes part of the dump: one append of the whole line.
    name.push_back('\n');
    if (auto r = write_all(index_fd.get(), name.data(), name.size(), index_path); !r) return r;
    if (options.sync_each_entry && ::fsync(index_fd.get()) != 0) {
      return fail("fsync of '" + index_path + "' failed: " + errno_text(errno));
    }
    last_micros[slot] = micros;
    ++counts[slot];
    return success();
  }
};

FakenectDumpWriter::FakenectDumpWriter(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
FakenectDumpWriter::FakenectDumpWriter(FakenectDumpWriter&&) noexcept = default;
FakenectDumpWriter& FakenectDumpWriter::operator=(FakenectDumpWriter&&) noexcept = default;
FakenectDumpWriter::~FakenectDumpWriter() = default;

Result<FakenectDumpWriter> FakenectDumpWriter::create(const std::filesystem::path& directory,
                                                      const KinectCalibration& calibration,
                                                      const DumpWriterOptions& options) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (fs::exists(directory, ec)) {
    if (!fs::is_directory(directory, ec)) {
      return fail("cannot record into '" + directory.string() +
                  "': it exists and is not a directory");
    }
    std::vector<fs::path> dump_files;
    bool non_empty = false;
    for (const auto& item : fs::directory_iterator(directory, ec)) {
      non_empty = true;
      const auto file = item.path().filename().string();
      if (item.is_regular_file() && is_dump_file_name(file)) dump_files.push_back(item.path());
    }
    if (ec) return fail("cannot list '" + directory.string() + "': " + ec.message());
    if (non_empty && !options.overwrite) {
      return fail("cannot record into '" + directory.string() +
                  "': the directory is not empty; choose a new directory or allow overwriting");
    }
    for (const auto& file : dump_files) {
      fs::remove(file, ec);
      if (ec) return fail("cannot remove old dump file '" + file.string() + "': " + ec.message());
    }
  } else {
    fs::create_directories(directory, ec);
    if (ec) {
      return fail("cannot create recording directory '" + directory.string() +
                  "': " + ec.message());
    }
  }

  auto impl = std::make_unique<Impl>();
  impl->directory = directory;
  impl->directory_string = directory.string();
  impl->options = options;
  if (auto r = write_device_json(directory / kDumpDeviceJsonFileName, calibration); !r) {
    return r.failure();
  }
  impl->index_path = (directory / kDumpIndexFileName).string();
  impl->index_fd = UniqueFd(
      ::open(impl->index_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_APPEND | O_CLOEXEC, 0644));
  if (!impl->index_fd.valid()) {
    const int err = errno;
    return fail("cannot create '" + impl->index_path + "': " + errno_text(err));
  }
  impl->buffer.reserve(640 * 480 * 3 + 64);
  impl->name.reserve(96);
  impl->path.reserve(impl->directory_string.size() + 96);
  return FakenectDumpWriter(std::move(impl));
}

Result<void> FakenectDumpWriter::write_depth(const DisparityImage& raw, double host_time_s,
                                             std::uint32_t device_timestamp) {
  if (raw.empty()) return fail("cannot record an empty depth image");
  encode_depth_pgm(raw, impl_->buffer);
  return impl_->write_entry(DumpEntryType::kDepth, host_time_s, device_timestamp);
}

Result<void> FakenectDumpWriter::write_color(const ColorImage& rgb, double host_time_s,
                                             std::uint32_t device_timestamp) {
  if (rgb.empty()) return fail("cannot record an empty colour image");
  encode_color_ppm(rgb, impl_->buffer);
  return impl_->write_entry(DumpEntryType::kColor, host_time_s, device_timestamp);
}

Result<void> FakenectDumpWriter::write_accel(const AccelSample& sample, double host_time_s,
                                             std::uint32_t device_timestamp) {
  encode_accel_dump(sample, impl_->buffer);
  return impl_->write_entry(DumpEntryType::kAccel, host_time_s, device_timestamp);
}

Result<void> FakenectDumpWriter::finish() {
  Impl& m = *impl_;
  if (m.finished) return success();
  m.finished = true;
  if (m.options.sync_each_entry) ::fsync(m.index_fd.get());
  if (const int err = m.index_fd.close_checked(); err != 0) {
    return fail("error closing '" + m.index_path + "': " + errno_text(err));
  }
  return success();
}

const std::filesystem::path& FakenectDumpWriter::directory() const {
  return impl_->directory;
}
long long FakenectDumpWriter::depth_count() const {
  return impl_->counts[0];
}
long long FakenectDumpWriter::color_count() const {
  return impl_->counts[1];
}
long long FakenectDumpWriter::accel_count() const {
  return impl_->counts[2];
}

}  // namespace fb
