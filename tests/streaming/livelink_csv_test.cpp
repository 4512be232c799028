#include "storage/export/livelink_csv.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include <gtest/gtest.h>

namespace fb {
namespace {

std::filesystem::path temp_file(const std::string& name) {
  return std::filesystem::temp_directory_path() /
         ("facebooth-llcsv-" + std::to_string(::getpid()) + "-" + name);
}

TEST(LiveLinkCsv, RoundTripsATake) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::vector<LiveLinkRow> rows;
  for (int f = 0; f < 95; ++f) {  // crosses a second boundary
    ArkitFrame frame;
    frame.index = f;
    frame.time_s = 3723.0 + f / 30.0;  // 01:02:03
    for (auto& w : frame.weights) w = u(rng);
    frame.weights[51] = 0.0f;  // tongueOut
    const Eigen::Quaterniond flip(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()));
    frame.camera_from_model.rotation =
        flip * head_from_angles({0.3 * u(rng) - 0.15, 0.2 * u(rng) - 0.1, 0.1 * u(rng) - 0.05});
    rows.push_back(to_livelink_row(frame));
  }
  const auto path = temp_file("take.csv");
  ASSERT_TRUE(write_livelink_csv(path, rows, 30.0).ok());
  std::ifstream in(path);
  std::string header;
  std::getline(in, header);
  EXPECT_EQ(header.rfind("Timecode,BlendShapeCount,EyeBlinkLeft,EyeLookDownLeft,", 0), 0u);
  EXPECT_NE(header.find(",TongueOut,HeadYaw,HeadPitch,HeadRoll,LeftEyeYaw"), std::string::npos);
  std::string first;
  std::getline(in, first);
  EXPECT_EQ(first.rfind("01:02:03:00.000,61,", 0), 0u) << first;

  auto read = read_livelink_csv(path, 30.0);
  ASSERT_TRUE(read.ok()) << read.error().message;
  ASSERT_EQ(read->size(), rows.size());
  for (std::size_t f = 0; f < rows.size(); ++f) {
    EXPECT_NEAR((*read)[f].time_s, rows[f].time_s, 1e-4);
    for (int i = 0; i < kArkitShapeCount; ++i) {
      EXPECT_NEAR((*read)[f].weights[i], rows[f].weights[i], 1e-6);
    }
    EXPECT_NEAR((*read)[f].head.yaw, rows[f].head.yaw, 1e-6);
    EXPECT_NEAR((*read)[f].head.pitch, rows[f].head.pitch, 1e-6);
    EXPECT_NEAR((*read)[f].head.roll, rows[f].head.roll, 1e-6);
  }
  std::filesystem::remove(path);
}

std::vector<std::string> split_line(const std::string& line) {
  std::vector<std::string> fields;
  std::stringstream ss(line);
  std::string field;
  while (std::getline(ss, field, ',')) fields.push_back(field);
  return fields;
}

// The app's own header (a fixture copied from a published Live Link Face take): facebooth's CSV
// has the same 63 columns in the same order, and every column holds the curve its name says.
TEST(LiveLinkCsv, ColumnsMatchTheAppsHeaderOneByOne) {
  std::ifstream fixture(FB_LIVELINK_HEADER_FIXTURE);
  ASSERT_TRUE(fixture) << "missing fixture " << FB_LIVELINK_HEADER_FIXTURE;
  std::string app_header;
  std::getline(fixture, app_header);
  const auto app_columns = split_line(app_header);
  ASSERT_EQ(app_columns.size(), 63u);

  // Distinct values per curve (curve i = (i + 1) / 100) and head angles, at 60 fps, starting at
  // the app's example time of day 12:27:47, frame 47 and .169 of a frame.
  LiveLinkRow row;
  for (int i = 0; i < kArkitShapeCount; ++i) row.weights[i] = (i + 1) / 100.0f;
  row.head = {0.25, -0.125, 0.0625};
  const double fps = 60.0;
  const double start = 12 * 3600.0 + 27 * 60.0 + 47.0 + 47.169 / fps;
  const auto path = temp_file("columns.csv");
  ASSERT_TRUE(write_livelink_csv(path, std::span<const LiveLinkRow>(&row, 1), fps, start).ok());
  std::ifstream in(path);
  std::string header, line;
  std::getline(in, header);
  std::getline(in, line);
  const auto columns = split_line(header);
  const auto fields = split_line(line);
  ASSERT_EQ(columns.size(), app_columns.size());
  ASSERT_EQ(fields.size(), app_columns.size());
  int curves_checked = 0;
  for (std::size_t c = 0; c < app_columns.size(); ++c) {
    EXPECT_EQ(columns[c], app_columns[c]) << "column " << c;
    const auto it = std::find(kLiveLinkNames.begin(), kLiveLinkNames.end(), app_columns[c]);
    if (it == kLiveLinkNames.end()) continue;
    const int curve = static_cast<int>(it - kLiveLinkNames.begin());
    EXPECT_NEAR(std::stod(fields[c]), (curve + 1) / 100.0, 1e-6) << app_columns[c];
    ++curves_checked;
  }
  EXPECT_EQ(curves_checked, kArkitShapeCount);
  // The pairs the app writes right before left sit where the app has them.
  EXPECT_EQ(columns[17], "JawRight");
  EXPECT_EQ(columns[18], "JawLeft");
  EXPECT_EQ(columns[23], "MouthRight");
  EXPECT_EQ(columns[24], "MouthLeft");
  EXPECT_EQ(fields[0], "12:27:47:47.169");
  EXPECT_EQ(fields[1], "61");
  EXPECT_NEAR(std::stod(fields[54]), 0.25, 1e-6);    // HeadYaw
  EXPECT_NEAR(std::stod(fields[55]), -0.125, 1e-6);  // HeadPitch
  EXPECT_NEAR(std::stod(fields[56]), 0.0625, 1e-6);  // HeadRoll
  std::filesystem::remove(path);
}

// The Timecode is a time of day with the frame number at the take's rate.
TEST(LiveLinkCsv, TimecodeIsTheTimeOfDayAtTheTakesRate) {
  EXPECT_EQ(livelink_timecode(12 * 3600.0 + 27 * 60.0 + 47.0 + 47.5 / 60.0, 60.0),
            "12:27:47:47.500");
  EXPECT_EQ(livelink_timecode(12 * 3600.0 + 27 * 60.0 + 47.0 + 29.0 / 30.0, 30.0),
            "12:27:47:29.000");
  EXPECT_EQ(livelink_timecode(86399.0 + 59.0 / 60.0 + 1.0 / 60.0, 60.0), "00:00:00:00.000");
  // Consecutive rows of a 30 fps take starting at 23:59:59 frame 28 cross midnight.
  const double start = 86399.0 + 28.0 / 30.0;
  EXPECT_EQ(livelink_timecode(start + 1.0 / 30.0, 30.0), "23:59:59:29.000");
  EXPECT_EQ(livelink_timecode(start + 2.0 / 30.0, 30.0), "00:00:00:00.000");
  // The store's UTC created_at read as a local time of day (TZ=UTC here: the same clock time).
  ::setenv("TZ", "UTC", 1);
  ::tzset();
  auto tod = local_time_of_day_s("2026-12-06T12:27:47.250Z");
  ASSERT_TRUE(tod.ok()) << tod.error().message;
  EXPECT_NEAR(*tod, 12 * 3600.0 + 27 * 60.0 + 47.25, 1e-6);
  EXPECT_FALSE(local_time_of_day_s("yesterday").ok());
}

TEST(LiveLinkCsv, HeadAnglesMatchTheConstruction) {
  const HeadAngles a{0.2, -0.1, 0.05};
  const HeadAngles b = head_angles(head_from_angles(a));
  EXPECT_NEAR(a.yaw, b.yaw, 1e-12);
  EXPECT_NEAR(a.pitch, b.pitch, 1e-12);
  EXPECT_NEAR(a.roll, b.roll, 1e-12);
}

TEST(LiveLinkCsv, ReadsColumnsByNameAndRejectsBadFiles) {
  const auto path = temp_file("app.csv");
  {
    std::ofstream out(path);
    out << "Timecode,BlendShapeCount,JawOpen,HeadYaw,Unknown\r\n"
        << "00:00:01:15.500,61,0.75,0.125,9\r\n";
  }
  auto read = read_livelink_csv(path, 30.0);
  ASSERT_TRUE(read.ok()) << read.error().message;
  ASSERT_EQ(read->size(), 1u);
  EXPECT_NEAR((*read)[0].time_s, 1.0 + 15.5 / 30.0, 1e-9);
  EXPECT_FLOAT_EQ((*read)[0].weights[17], 0.75f);  // JawOpen
  EXPECT_DOUBLE_EQ((*read)[0].head.yaw, 0.125);
  {
    std::ofstream out(path);
    out << "Timecode,BlendShapeCount,JawOpen\n00:00:01:15.500,61,zero\n";
  }
  EXPECT_FALSE(read_livelink_csv(path, 30.0).ok());
  {
    std::ofstream out(path);
    out << "Timecode,BlendShapeCount,JawOpen\n00:00:01,61\n";
  }
  EXPECT_FALSE(read_livelink_csv(path, 30.0).ok());
  EXPECT_FALSE(read_livelink_csv(temp_file("missing.csv"), 30.0).ok());
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace fb
