// Reading and writing fakenect dumps (libfreenect's `fakenect-record` format), the format of the
// real Kinect recordings in shared/kinect and of the project's own recordings.
//
// A dump is a directory with
//   INDEX.txt     one file name per line, in the order the data arrived
//   d-<host time>-<device timestamp>.pgm   depth: "P5 640 480 65535\n" + 640*480 uint16 raw 11-bit
//                                          disparity in the recording host's byte order
//                                          (little-endian on x86/ARM; fakenect fwrite()s the
//                                          buffer as is, despite PGM being big-endian by spec)
//   r-<host time>-<device timestamp>.ppm   colour: "P6 640 480 255\n" + 640*480 RGB8
//   a-<host time>-<device timestamp>.dump  accelerometer: freenect_raw_tilt_state, 12 bytes
//   device.json   optional registration data (see device_json.hpp)
// <host time> is the recording host's clock in seconds with 6 decimals ("%f"); the device
// timestamp is the Kinect's 32-bit 60 MHz counter ("%u").
//
// Frames: one RgbdFrame per depth image, in INDEX order. Its colour image is the last `r-`
// entry at or before the depth entry in INDEX.txt (Kinect depth and colour are not captured
// together; this is what a live consumer would have seen). A depth entry before the first
// colour entry gets the first colour entry of the dump instead. Dumps without colour give
// frames with an empty colour image.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "algo/core/frame.hpp"
#include "algo/core/image.hpp"
#include "algo/core/result.hpp"
#include "algo/sensor/kinect_calibration.hpp"

namespace fb {

inline constexpr const char* kDumpIndexFileName = "INDEX.txt";
inline constexpr const char* kDumpDeviceJsonFileName = "device.json";

enum class DumpEntryType : char {
  kDepth = 'd',  // .pgm
  kColor = 'r',  // .ppm
  kAccel = 'a',  // .dump
};

// One line of INDEX.txt.
struct DumpEntry {
  DumpEntryType type = DumpEntryType::kDepth;
  double host_time_s = 0.0;
  std::uint32_t device_timestamp = 0;
  std::string file_name;  // as written in INDEX.txt, relative to the dump directory
};

// libfreenect's freenect_raw_tilt_state, as fakenect-record dumps it (12 bytes, little-endian:
// three int16 accelerometer counts (819 per g), int8 tilt angle in half degrees, one padding
// byte, int32 tilt status).
struct AccelSample {
  std::int16_t accelerometer_x = 0;
  std::int16_t accelerometer_y = 0;
  std::int16_t accelerometer_z = 0;
  std::int8_t tilt_angle = 0;
  std::int32_t tilt_status = 0;
};
inline constexpr std::size_t kAccelDumpSize = 12;

// Parses a dump file name such as `d-1513096835.219278-2320228015.pgm`; the extension must match
// the type (d: pgm, r: ppm, a: dump).
Result<DumpEntry> parse_dump_file_name(std::string_view name);

// Formats a dump file name into `out` (reusing its capacity). The host time is rounded to whole
// microseconds, like fakenect's "%f"; negative times are written as 0.
void format_dump_file_name(DumpEntryType type, double host_time_s, std::uint32_t device_timestamp,
                           std::string& out);

// Single-file codecs. `scratch` holds the file bytes and is reused across calls so steady-state
// reading does not allocate. Errors name the file and what is wrong with it.
//
// Depth: P5 with maxval 65535 (or 2047), 16-bit samples. fakenect dumps are little-endian; a
// big-endian (spec-conforming) file is recognised because its little-endian reading exceeds 11
// bits while its big-endian reading does not. Every value must be <= 2047.
Result<void> read_depth_pgm(const std::string& path, DisparityImage& out,
                            std::vector<std::uint8_t>& scratch);
// Colour: P6 with maxval 255.
Result<void> read_color_ppm(const std::string& path, ColorImage& out,
                            std::vector<std::uint8_t>& scratch);
Result<AccelSample> read_accel_dump(const std::string& path, std::vector<std::uint8_t>& scratch);
Result<AccelSample> read_accel_dump(const std::string& path);

// Encoders producing exactly what fakenect-record writes (depth little-endian).
void encode_depth_pgm(const DisparityImage& raw, std::vector<std::uint8_t>& out);
void encode_color_ppm(const ColorImage& rgb, std::vector<std::uint8_t>& out);
void encode_accel_dump(const AccelSample& sample, std::vector<std::uint8_t>& out);

// Sequential reader of a dump directory. Opening parses INDEX.txt and device.json and checks that
// every listed file exists; images are read lazily, one frame per next() call, into the caller's
// frame buffers (no allocation once the buffers have their size).
class FakenectDumpReader {
 public:
  // Fails on a missing directory, a missing or unreadable INDEX.txt, an INDEX line that is not a
  // dump file name (an unterminated last line, as an interrupted recorder can leave, is ignored),
  // a listed file that does not exist, or an invalid device.json.
  static Result<FakenectDumpReader> open(const std::filesystem::path& directory);

  FakenectDumpReader(FakenectDumpReader&&) noexcept;
  FakenectDumpReader& operator=(FakenectDumpReader&&) noexcept;
  ~FakenectDumpReader();

  const std::filesystem::path& directory() const;
  const std::vector<DumpEntry>& entries() const;  // every INDEX.txt line, in order
  std::size_t depth_frame_count() const;          // number of frames next() will deliver
  std::size_t color_image_count() const;
  // device.json's calibration, or nullopt when the dump has no device.json.
  const std::optional<KinectCalibration>& device_calibration() const;

  // Reads the next frame: index, depth/colour host times and device timestamps, raw_disparity
  // and color. frame.depth_mm is left untouched (converting needs a calibration; see
  // KinectRegistration). Returns false after the last frame. A colour image shared by
  // consecutive frames is read from disk only once.
  Result<bool> next(RgbdFrame& frame);
  // The latest accelerometer sample at or before the last frame's depth entry, if the dump has one.
  const std::optional<AccelSample>& accel() const;
  // Host time of depth frame `i` (for pacing), without reading it.
  double depth_host_time(std::size_t i) const;
  std::size_t position() const;  // frames delivered since open() or rewind()
  void rewind();

 private:
  struct Impl;
  explicit FakenectDumpReader(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

struct DumpWriterOptions {
  // A non-empty directory is refused unless this is set; then its dump files (INDEX.txt,
  // device.json, d-/r-/a- files) are deleted first. Other files are left alone.
  bool overwrite = false;
  // fsync() each file and INDEX.txt after every entry (survives power loss, much slower).
  bool sync_each_entry = false;
};

// Writes a dump that fakenect and FakenectDumpReader both play. Each image file is written
// completely and closed before its INDEX.txt line is appended (one write() call), so a recording
// interrupted at any point is a valid, shorter dump. Names are kept unique per type: an entry
// whose microsecond host time is not after the previous entry of the same type is moved 1 us
// later.
class FakenectDumpWriter {
 public:
  // Creates `directory` (and parents) if needed, writes device.json and an empty INDEX.txt.
  static Result<FakenectDumpWriter> create(const std::filesystem::path& directory,
                                           const KinectCalibration& calibration,
                                           const DumpWriterOptions& options = {});

  FakenectDumpWriter(FakenectDumpWriter&&) noexcept;
  FakenectDumpWriter& operator=(FakenectDumpWriter&&) noexcept;
  ~FakenectDumpWriter();  // closes INDEX.txt; what was written stays a valid dump

  Result<void> write_depth(const DisparityImage& raw, double host_time_s,
                           std::uint32_t device_timestamp);
  Result<void> write_color(const ColorImage& rgb, double host_time_s,
                           std::uint32_t device_timestamp);
  Result<void> write_accel(const AccelSample& sample, double host_time_s,
                           std::uint32_t device_timestamp);
  // Closes INDEX.txt (fsyncs the directory contents); later writes fail.
  Result<void> finish();

  const std::filesystem::path& directory() const;
  long long depth_count() const;
  long long color_count() const;
  long long accel_count() const;

 private:
  struct Impl;
  explicit FakenectDumpWriter(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace fb
