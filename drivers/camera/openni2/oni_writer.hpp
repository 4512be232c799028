// A minimal writer for OpenNI2 `.oni` recordings (the container libOniFile plays back).
//
// Why it exists: openni::Recorder can only record VideoStreams of an open Device, and without a
// sensor or a recording there is nothing to open. Writing the container ourselves gives the
// project (and its tests) recordings with known content that go through the real OniFile player.
//
// The layout mirrors what OpenNI2's own FileRecorder (Source/Core/OniFileRecorder.cpp and
// OniDataRecords.cpp, Apache-2.0) emits, reimplemented from the format description:
//   file header  "NI10", version 1.0.1.0, max timestamp, max node id            (24 bytes)
//   per stream   NodeAdded + the properties the player turns into a video mode
//   per stream   NodeStateReady, NodeDataBegin
//   per frame    NewData (timestamp, 1-based frame number, uncompressed payload "NONE")
//   at close     per stream NodeRemoved + SeekTable, then End; NodeAdded records and the file
//                header are patched with the final frame counts, timestamps and seek positions.
// Every record starts with a 28-byte header: magic "NIR\0", type, node id, fields size
// (including the header), payload size, 64-bit undo position. All integers little-endian, packed.
#pragma once

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "algo/core/image.hpp"
#include "algo/core/result.hpp"

namespace fb {

// Fields of view (radians) OpenNI's PS1080 driver reports for a Kinect v1 / PrimeSense sensor.
inline constexpr double kPs1080DepthHfov = 1.0144686707507438;
inline constexpr double kPs1080DepthVfov = 0.78980943449644714;
inline constexpr double kPs1080ColorHfov = 1.0225999629112853;
inline constexpr double kPs1080ColorVfov = 0.79661567870308419;

struct OniWriterOptions {
  int width = 640;
  int height = 480;
  int fps = 30;
  bool with_color = true;  // false writes a depth-only recording
  // Fields of view in radians, stored as the player's "xnFOV" property and reported by
  // VideoStream::get{Horizontal,Vertical}FieldOfView on playback.
  double depth_hfov = kPs1080DepthHfov;
  double depth_vfov = kPs1080DepthVfov;
  double color_hfov = kPs1080ColorHfov;
  double color_vfov = kPs1080ColorVfov;
  // Largest depth value the stream can hold (the player's ONI_STREAM_PROPERTY_MAX_VALUE).
  std::uint16_t max_depth_mm = 10000;
  std::string original_device = "facebooth OniWriter";
};

class OniWriter {
 public:
  // Creates (truncates) `path` and writes the header and stream descriptions.
  static Result<std::unique_ptr<OniWriter>> create(const std::filesystem::path& path,
                                                   const OniWriterOptions& options = {});
  ~OniWriter();  // finishes the file if close() was not called; errors are lost then
  OniWriter(const OniWriter&) = delete;
  OniWriter& operator=(const OniWriter&) = delete;

  // Appends one frame per stream. `depth` must be width x height millimetres; `color` must be
  // width x height when the recording has colour and is ignored otherwise. Timestamps are in
  // microseconds and must not decrease.
  Result<void> write(const DepthImage& depth, const ColorImage& color, std::uint64_t timestamp_us);
  // Depth-only variant for recordings without colour.
  Result<void> write(const DepthImage& depth, std::uint64_t timestamp_us);

  // Writes the trailing records and patches the header. Idempotent.
  Result<void> close();

  long long frames_written() const { return frame_count_; }

 private:
  struct SeekEntry {
    std::uint64_t timestamp = 0;
    std::uint64_t position = 0;
  };
  struct Node {
    std::uint32_t id = 0;
    std::uint32_t type = 0;  // 2 = depth, 3 = image (OpenNI 1.x production node types)
    std::uint64_t node_added_position = 0;
    std::uint64_t last_new_data_position = 0;
    std::vector<SeekEntry> seek_table;
  };

  OniWriter(std::filesystem::path path, const OniWriterOptions& options);
  Result<void> write_preamble();
  Result<void> write_node_description(Node& node);
  Result<void> write_new_data(Node& node, const void* data, std::uint32_t size,
                              std::uint64_t timestamp_us);
  Result<void> write_frame(const DepthImage& depth, const ColorImage* color,
                           std::uint64_t timestamp_us);
  Result<void> emit(std::uint64_t* position = nullptr);  // writes record_ at the end of the file
  Result<void> check_stream(const char* what);

  std::filesystem::path path_;
  OniWriterOptions options_;
  std::ofstream file_;
  std::vector<std::uint8_t> record_;  // the record being assembled; reused for every record
  Node depth_node_;
  Node color_node_;
  long long frame_count_ = 0;
  std::uint64_t max_timestamp_ = 0;
  bool closed_ = false;
};

}  // namespace fb
