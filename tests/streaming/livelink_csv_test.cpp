#include "storage/export/livelink_csv.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>

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
