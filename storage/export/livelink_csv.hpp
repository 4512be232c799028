// Live Link Face CSV (Epic's iOS app's take format) as the app writes it, so takes open in the
// tools that read those files (Unreal, Blender and Maya importers), including those that go by
// column position:
//   Timecode,BlendShapeCount,EyeBlinkLeft,...,JawForward,JawRight,JawLeft,JawOpen,...,
//   MouthPucker,MouthRight,MouthLeft,MouthSmileLeft,...,TongueOut,HeadYaw,HeadPitch,HeadRoll,
//   LeftEyeYaw,LeftEyePitch,LeftEyeRoll,RightEyeYaw,RightEyePitch,RightEyeRoll
// (the curve columns in kLiveLinkCsvOrder; the app's own header is kept as a test fixture,
// tests/streaming/fixtures/livelink_face_header.csv).
// - Timecode "HH:MM:SS:FF.fff": the time of day (as the app's system-clock timecode, e.g.
//   12:27:47:47.169), the frame within the second at the take's rate and the sub-frame
//   fraction (3 decimals). A row's time of day is the writer's `start_of_day_s` (the time of
//   day of time_s = 0) plus its time_s, wrapped at midnight.
// - BlendShapeCount: 61 (52 curves + 3 head + 6 eye angles), as the app writes.
// - Curves in [0, 1] (6 decimals); head angles in radians (see algo/tracking/arkit.hpp for the
//   axes); the eye angles are 0 (the tracker does not estimate gaze).
// The reader accepts any column order (it goes by the header names), so files from the app
// itself read too; unknown columns are ignored and missing curves are 0.
#pragma once

#include <array>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <span>
#include <string>
#include <string_view>
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

// Header line and one row as text (no trailing newline); `start_of_day_s` as above.
std::string livelink_csv_header();
std::string format_livelink_row(const LiveLinkRow& row, double fps, double start_of_day_s = 0.0);

// Seconds since local midnight of a moment (the system clock, or a UTC ISO-8601 text such as the
// store's created_at "2026-12-06T00:25:31.123Z"); the Timecode's origin.
double local_time_of_day_s(std::chrono::system_clock::time_point when);
Result<double> local_time_of_day_s(std::string_view utc_iso8601);

// Timecode of a time in seconds at `fps`, and back.
std::string livelink_timecode(double time_s, double fps);
Result<double> parse_livelink_timecode(std::string_view text, double fps);

// Writes a whole take. The reader's time_s is the Timecode's time of day in seconds.
Result<void> write_livelink_csv(const std::filesystem::path& path,
                                std::span<const LiveLinkRow> rows, double fps,
                                double start_of_day_s = 0.0);
Result<std::vector<LiveLinkRow>> read_livelink_csv(const std::filesystem::path& path, double fps);

// Appends rows as they come (the live `facebooth track --csv`); flushes on close/destruction.
class LiveLinkCsvWriter {
 public:
  static Result<LiveLinkCsvWriter> open(const std::filesystem::path& path, double fps,
                                        double start_of_day_s = 0.0);
  // The time of day of time_s = 0 for the rows appended from now on.
  void set_start_of_day_s(double start_of_day_s) { start_of_day_s_ = start_of_day_s; }
  Result<void> append(const LiveLinkRow& row);
  Result<void> close();

 private:
  LiveLinkCsvWriter() = default;
  std::filesystem::path path_;
  double fps_ = 30.0;
  double start_of_day_s_ = 0.0;
  std::ofstream out_;
};

}  // namespace fb
