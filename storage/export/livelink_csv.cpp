#include "storage/export/livelink_csv.hpp"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <sstream>

namespace fb {
namespace {

constexpr std::array<std::string_view, 9> kAngleColumns = {
    "HeadYaw",     "HeadPitch",   "HeadRoll",      "LeftEyeYaw",  "LeftEyePitch",
    "LeftEyeRoll", "RightEyeYaw", "RightEyePitch", "RightEyeRoll"};
constexpr int kBlendShapeCount = kArkitShapeCount + 9;  // 61, as the app writes

void append_number(std::string& out, double value) {
  char buffer[48];
  const auto [end, ec] =
      std::to_chars(buffer, buffer + sizeof(buffer), value, std::chars_format::fixed, 6);
  out.append(buffer, ec == std::errc() ? end : buffer);
}

Result<double> parse_double(std::string_view text, std::string_view what) {
  while (!text.empty() && (text.front() == ' ' || text.front() == '\r')) text.remove_prefix(1);
  while (!text.empty() && (text.back() == ' ' || text.back() == '\r')) text.remove_suffix(1);
  double value = 0.0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || end != text.data() + text.size()) {
    return fail("Live Link CSV: bad number '" + std::string(text) + "' in column " +
                std::string(what));
  }
  return value;
}

std::vector<std::string_view> split(std::string_view line) {
  std::vector<std::string_view> fields;
  std::size_t start = 0;
  while (true) {
    const auto comma = line.find(',', start);
    fields.push_back(
        line.substr(start, comma == std::string_view::npos ? line.npos : comma - start));
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
  return fields;
}

}  // namespace

LiveLinkRow to_livelink_row(const ArkitFrame& frame) {
  LiveLinkRow row;
  row.time_s = frame.time_s;
  row.weights = frame.weights;
  row.head = head_angles(head_rotation(frame.camera_from_model));
  return row;
}

std::string livelink_timecode(double time_s, double fps) {
  if (!(time_s >= 0.0)) time_s = 0.0;
  time_s = std::fmod(time_s, 86400.0);  // a time of day: wraps at midnight
  const double frames_total = time_s * fps;
  // Whole frames, and the fraction of a frame (rounded to 3 decimals, carrying into the frame).
  long long whole = static_cast<long long>(std::floor(frames_total));
  long long milli = std::llround((frames_total - static_cast<double>(whole)) * 1000.0);
  if (milli >= 1000) {
    ++whole;
    milli -= 1000;
  }
  const long long per_second = std::max(1LL, std::llround(fps));
  const long long seconds_total = whole / per_second;
  const long long frame = whole % per_second;
  char buffer[128];
  std::snprintf(buffer, sizeof(buffer), "%02lld:%02lld:%02lld:%02lld.%03lld",
                (seconds_total / 3600) % 24, (seconds_total / 60) % 60, seconds_total % 60, frame,
                milli);
  return buffer;
}

Result<double> parse_livelink_timecode(std::string_view text, double fps) {
  int h = 0, m = 0, s = 0;
  double f = 0.0;
  const std::string copy(text);
  if (std::sscanf(copy.c_str(), "%d:%d:%d:%lf", &h, &m, &s, &f) != 4 || h < 0 || m < 0 || m > 59 ||
      s < 0 || s > 59 || f < 0.0) {
    return fail("Live Link CSV: bad timecode '" + copy + "'; expected HH:MM:SS:FF.fff");
  }
  const long long per_second = std::max(1LL, std::llround(fps));
  return (static_cast<double>(h) * 3600.0 + m * 60.0 + s) + f / static_cast<double>(per_second);
}

double local_time_of_day_s(std::chrono::system_clock::time_point when) {
  const auto since_epoch = when.time_since_epoch();
  const std::time_t seconds =
      static_cast<std::time_t>(std::chrono::floor<std::chrono::seconds>(since_epoch).count());
  const double fraction =
      std::chrono::duration<double>(since_epoch - std::chrono::seconds(seconds)).count();
  std::tm local{};
  localtime_r(&seconds, &local);
  return local.tm_hour * 3600.0 + local.tm_min * 60.0 + local.tm_sec + fraction;
}

Result<double> local_time_of_day_s(std::string_view utc_iso8601) {
  std::tm utc{};
  double sec = 0.0;
  const std::string text(utc_iso8601);
  if (std::sscanf(text.c_str(), "%d-%d-%dT%d:%d:%lf", &utc.tm_year, &utc.tm_mon, &utc.tm_mday,
                  &utc.tm_hour, &utc.tm_min, &sec) != 6) {
    return fail("Live Link CSV: cannot read the time '" + text +
                "' (expected YYYY-MM-DDTHH:MM:SS.sssZ, UTC)");
  }
  utc.tm_year -= 1900;
  utc.tm_mon -= 1;
  utc.tm_sec = static_cast<int>(std::floor(sec));
  const std::time_t t = timegm(&utc);
  return local_time_of_day_s(std::chrono::system_clock::from_time_t(t) +
                             std::chrono::duration_cast<std::chrono::system_clock::duration>(
                                 std::chrono::duration<double>(sec - std::floor(sec))));
}

std::string livelink_csv_header() {
  std::string out = "Timecode,BlendShapeCount";
  for (int k : kLiveLinkCsvOrder) {
    out += ',';
    out += kLiveLinkNames[static_cast<std::size_t>(k)];
  }
  for (auto name : kAngleColumns) {
    out += ',';
    out += name;
  }
  return out;
}

std::string format_livelink_row(const LiveLinkRow& row, double fps, double start_of_day_s) {
  std::string out = livelink_timecode(start_of_day_s + row.time_s, fps);
  out += ',';
  out += std::to_string(kBlendShapeCount);
  for (int k : kLiveLinkCsvOrder) {
    out += ',';
    append_number(out, row.weights[static_cast<std::size_t>(k)]);
  }
  for (double a : {row.head.yaw, row.head.pitch, row.head.roll}) {
    out += ',';
    append_number(out, a);
  }
  for (float e : row.eyes) {
    out += ',';
    append_number(out, e);
  }
  return out;
}

Result<void> write_livelink_csv(const std::filesystem::path& path,
                                std::span<const LiveLinkRow> rows, double fps,
                                double start_of_day_s) {
  auto writer = LiveLinkCsvWriter::open(path, fps, start_of_day_s);
  if (!writer) return writer.failure();
  for (const auto& row : rows) {
    if (auto r = writer->append(row); !r) return r;
  }
  return writer->close();
}

Result<std::vector<LiveLinkRow>> read_livelink_csv(const std::filesystem::path& path, double fps) {
  std::ifstream in(path);
  if (!in) return fail("Live Link CSV: cannot open " + path.string());
  std::string line;
  if (!std::getline(in, line)) return fail("Live Link CSV: " + path.string() + " is empty");
  if (!line.empty() && line.back() == '\r') line.pop_back();
  const auto header = split(line);
  if (header.empty() || header[0] != "Timecode") {
    return fail("Live Link CSV: " + path.string() + " does not start with a Timecode column");
  }
  // Column -> slot: 0..51 curves, 100 + i angles, -1 ignored.
  std::vector<int> slot(header.size(), -1);
  for (std::size_t c = 1; c < header.size(); ++c) {
    for (int i = 0; i < kArkitShapeCount; ++i) {
      if (header[c] == kLiveLinkNames[i]) slot[c] = i;
    }
    for (int i = 0; i < 9; ++i) {
      if (header[c] == kAngleColumns[i]) slot[c] = 100 + i;
    }
  }
  std::vector<LiveLinkRow> rows;
  int line_number = 1;
  while (std::getline(in, line)) {
    ++line_number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty()) continue;
    const auto fields = split(line);
    if (fields.size() != header.size()) {
      return fail("Live Link CSV: line " + std::to_string(line_number) + " has " +
                  std::to_string(fields.size()) + " fields, the header " +
                  std::to_string(header.size()));
    }
    LiveLinkRow row;
    auto time = parse_livelink_timecode(fields[0], fps);
    if (!time) return fail(time.error().message + " (line " + std::to_string(line_number) + ")");
    row.time_s = *time;
    for (std::size_t c = 1; c < fields.size(); ++c) {
      if (slot[c] < 0) continue;
      auto value = parse_double(fields[c], header[c]);
      if (!value)
        return fail(value.error().message + " (line " + std::to_string(line_number) + ")");
      if (slot[c] < 100) {
        row.weights[static_cast<std::size_t>(slot[c])] = static_cast<float>(*value);
      } else if (slot[c] == 100) {
        row.head.yaw = *value;
      } else if (slot[c] == 101) {
        row.head.pitch = *value;
      } else if (slot[c] == 102) {
        row.head.roll = *value;
      } else {
        row.eyes[static_cast<std::size_t>(slot[c] - 103)] = static_cast<float>(*value);
      }
    }
    rows.push_back(row);
  }
  return rows;
}

Result<LiveLinkCsvWriter> LiveLinkCsvWriter::open(const std::filesystem::path& path, double fps,
                                                  double start_of_day_s) {
  if (!(fps > 0.0)) return fail("Live Link CSV: fps must be positive");
  LiveLinkCsvWriter writer;
  writer.path_ = path;
  writer.fps_ = fps;
  writer.start_of_day_s_ = start_of_day_s;
  writer.out_.open(path, std::ios::out | std::ios::trunc);
  if (!writer.out_) return fail("Live Link CSV: cannot create " + path.string());
  writer.out_ << livelink_csv_header() << '\n';
  return writer;
}

Result<void> LiveLinkCsvWriter::append(const LiveLinkRow& row) {
  out_ << format_livelink_row(row, fps_, start_of_day_s_) << '\n';
  if (!out_) return fail("Live Link CSV: writing " + path_.string() + " failed (disk full?)");
  return success();
}

Result<void> LiveLinkCsvWriter::close() {
  if (!out_.is_open()) return success();
  out_.flush();
  const bool ok = static_cast<bool>(out_);
  out_.close();
  if (!ok) return fail("Live Link CSV: writing " + path_.string() + " failed (disk full?)");
  return success();
}

}  // namespace fb
