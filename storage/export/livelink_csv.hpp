// Live Link Face style CSV (Epic's iOS app's take format), so takes open in the tools that read
// those files (Unreal, Blender and Maya importers):
//   Timecode,BlendShapeCount,EyeBlinkLeft,...,TongueOut,HeadYaw,HeadPitch,HeadRoll,
//   LeftEyeYaw,LeftEyePitch,LeftEyeRoll,RightEyeYaw,RightEyePitch,RightEyeRoll
// - Timecode "HH:MM:SS:FF.fff": hours, minutes, seconds, frame within the second at `fps`, and
//   the sub-frame fraction (3 decimals), from the frame's time.
// - BlendShapeCount: 61 (52 curves + 3 head + 6 eye angles), as the app writes.
// - Curves in [0, 1] (6 decimals); head angles in radians (see algo/tracking/arkit.hpp for the
//   axes); the eye angles are 0 (the tracker does not estimate gaze).
// The reader accepts any column order (it goes by the header names), so files from the app
// itself read too; unknown columns are ignored and missing curves are 0.
#pragma once

#include <array>
#include <filesystem>
#include <fstream>
#include <span>
#include <string>
#include <vector>

#include "algo/core/result.hpp"
#include "algo/tracking/arkit.hpp"

namespace fb {

struct LiveLinkRow {
  double time_s = 0.0;
  std::array<float, kArkitShapeCount> weights{};
  HeadAngles head;              // radians
  std::array<float, 6> eyes{};  // LeftEyeYaw ... RightEyeRoll, radians
};

LiveLinkRow to_livelink_row(const ArkitFrame& frame);

// Header line and one row as text (no trailing newline).
std::string livelink_csv_header();
std::string format_livelink_row(const LiveLinkRow& row, double fps);

// Timecode of a time in seconds at `fps`, and back.
std::string livelink_timecode(double time_s, double fps);
Result<double> parse_livelink_timecode(std::string_view text, double fps);

// Writes a whole take.
Result<void> write_livelink_csv(const std::filesystem::path& path,
                                std::span<const LiveLinkRow> rows, double fps);
Result<std::vector<LiveLinkRow>> read_livelink_csv(const std::filesystem::path& path, double fps);

// Appends rows as they come (the live `facebooth track --csv`); flushes on close/destruction.
class LiveLinkCsvWriter {
 public:
  static Result<LiveLinkCsvWriter> open(const std::filesystem::path& path, double fps);
  Result<void> append(const LiveLinkRow& row);
  Result<void> close();

 private:
  LiveLinkCsvWriter() = default;
  std::filesystem::path path_;
  double fps_ = 30.0;
  std::ofstream out_;
};

}  // namespace fb
