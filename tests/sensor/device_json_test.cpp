#include "drivers/camera/common/device_json.hpp"

#include <cstring>
#include <filesystem>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "tests/fuzz/regression_input.hpp"

namespace fb {
namespace {

// The openiss-desk dump's device.json, verbatim.
constexpr const char* kRealDeviceJson = R"({
    "reg_info": {
        "ax": 1830, "bx": 11, "cx": 31, "dx": 497, "ay": 56, "by": 2582, "cy": 641, "dy": 77,
        "dx_start": 3269, "dy_start": 8447, "dx_beta_start": 10062, "dy_beta_start": 130801,
        "dx_beta_inc": 170, "dy_beta_inc": 136, "dxdx_start": 2096139, "dxdy_start": 1537,
        "dydx_start": 8, "dydy_start": 2096178, "dxdxdx_start": 134215349,
        "dydxdx_start": 134217225, "dxdxdy_start": 134216993, "dydxdy_start": 134216795,
        "dydydx_start": 134217133, "dydydy_start": 134215132,
        "pad_info": {"start_lines": 0, "end_lines": 0, "cropping_lines": 0},
        "zero_plane_info": {
            "dcmos_emitter_distance": 7.5,
            "dcmos_rcmos_distance": 2.4000000953674316,
            "reference_distance": 120,
            "reference_pixel_size": 0.10419999808073044
        }
    },
    "const_shift": 200
})";

bool same(const KinectCalibration& a, const KinectCalibration& b) {
  return std::memcmp(&a.reg_info, &b.reg_info, sizeof a.reg_info) == 0 &&
         std::memcmp(&a.pad_info, &b.pad_info, sizeof a.pad_info) == 0 &&
         a.zero_plane_info.dcmos_emitter_distance == b.zero_plane_info.dcmos_emitter_distance &&
         a.zero_plane_info.dcmos_rcmos_distance == b.zero_plane_info.dcmos_rcmos_distance &&
         a.zero_plane_info.reference_distance == b.zero_plane_info.reference_distance &&
         a.zero_plane_info.reference_pixel_size == b.zero_plane_info.reference_pixel_size &&
         a.const_shift == b.const_shift;
}

TEST(DeviceJson, ParsesRealFileAndEqualsDefaults) {
  auto parsed = parse_device_json(kRealDeviceJson);
  ASSERT_TRUE(parsed) << parsed.error().message;
  EXPECT_TRUE(same(*parsed, KinectCalibration::defaults()));
  EXPECT_EQ(parsed->reg_info.dxdxdx_start, 134215349);
  EXPECT_EQ(parsed->const_shift, 200);
}

TEST(DeviceJson, RoundTrip) {
  KinectCalibration c = KinectCalibration::defaults();
  c.reg_info.ax = -5;  // negative values survive too
  c.pad_info.end_lines = 3;
  c.zero_plane_info.reference_pixel_size = 0.1041999980807304;
  c.const_shift = 201;
  const std::string text = to_device_json(c);
  auto parsed = parse_device_json(text);
  ASSERT_TRUE(parsed) << parsed.error().message;
  EXPECT_TRUE(same(*parsed, c));
  // Same layout as the real files: pad_info and zero_plane_info inside reg_info.
  const auto j = nlohmann::json::parse(text);
  EXPECT_TRUE(j["reg_info"].contains("zero_plane_info"));
  EXPECT_TRUE(j["reg_info"].contains("pad_info"));
  EXPECT_EQ(to_device_json(*parsed), text);
}

TEST(DeviceJson, CorrectionRoundTripAndRange) {
  KinectCalibration c = KinectCalibration::defaults();
  EXPECT_EQ(to_device_json(c).find("correction"), std::string::npos)
      << "an uncalibrated unit writes the real files' layout";
  c.correction.dx_px = -7.125;
  c.correction.dy_px = 13.5;
  c.correction.rotation_deg = 0.25;
  c.correction.depth_scale = 0.97;
  c.correction.inverse_depth_offset_per_m = 0.004;
  auto parsed = parse_device_json(to_device_json(c));
  ASSERT_TRUE(parsed) << parsed.error().message;
  EXPECT_DOUBLE_EQ(parsed->correction.dx_px, -7.125);
  EXPECT_DOUBLE_EQ(parsed->correction.dy_px, 13.5);
  EXPECT_DOUBLE_EQ(parsed->correction.rotation_deg, 0.25);
  EXPECT_DOUBLE_EQ(parsed->correction.depth_scale, 0.97);
  EXPECT_DOUBLE_EQ(parsed->correction.inverse_depth_offset_per_m, 0.004);
  auto j = nlohmann::json::parse(to_device_json(c));
  j["correction"]["depth_scale"] = 3.0;
  auto bad = parse_device_json(j.dump());
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().message.find("correction.depth_scale"), std::string::npos);
  j["correction"] = "x";
  EXPECT_FALSE(parse_device_json(j.dump()));
}

TEST(DeviceJson, FileRoundTrip) {
  const auto dir =
      std::filesystem::temp_directory_path() /
      ("fb_device_json_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()));
  std::filesystem::create_directories(dir);
  const auto file = dir / "device.json";
  ASSERT_TRUE(write_device_json(file, KinectCalibration::defaults()));
  auto read = read_device_json(file);
  ASSERT_TRUE(read) << read.error().message;
  EXPECT_TRUE(same(*read, KinectCalibration::defaults()));
  auto missing = read_device_json(dir / "nope.json");
  ASSERT_FALSE(missing);
  EXPECT_NE(missing.error().message.find("nope.json"), std::string::npos);
  std::filesystem::remove_all(dir);
}

TEST(DeviceJson, AcceptsTopLevelBlocks) {
  auto j = nlohmann::json::parse(kRealDeviceJson);
  j["zero_plane_info"] = j["reg_info"]["zero_plane_info"];
  j["pad_info"] = j["reg_info"]["pad_info"];
  j["reg_info"].erase("zero_plane_info");
  j["reg_info"].erase("pad_info");
  auto parsed = parse_device_json(j.dump());
  ASSERT_TRUE(parsed) << parsed.error().message;
  EXPECT_TRUE(same(*parsed, KinectCalibration::defaults()));
}

std::string error_of(const std::string& text) {
  auto parsed = parse_device_json(text);
  EXPECT_FALSE(parsed);
  return parsed ? std::string() : parsed.error().message;
}

// Found by device_json_fuzz: a number too large for a double ("ax": 1e1539) made nlohmann throw
// out_of_range, not parse_error, and the exception escaped the parser (std::terminate): a
// damaged device.json took down the replay camera instead of being reported.
TEST(DeviceJson, NumberOverflowIsAnErrorNotAnException) {
  const std::string text = test::fuzz_regression("device_json_fuzz", "number-overflow-1e1539");
  ASSERT_NE(text.find("1e1539"), std::string::npos);
  auto parsed = parse_device_json(text);
  ASSERT_FALSE(parsed);
  EXPECT_NE(parsed.error().message.find("not valid JSON"), std::string::npos)
      << parsed.error().message;
  EXPECT_FALSE(parse_device_json(R"({"reg_info": {"ax": 1e400}, "const_shift": 200})"));
}

TEST(DeviceJson, ErrorsNameTheField) {
  auto j = nlohmann::json::parse(kRealDeviceJson);
  {
    auto k = j;
    k["reg_info"].erase("dx_start");
    EXPECT_NE(error_of(k.dump()).find("'reg_info.dx_start' is missing"), std::string::npos);
  }
  {
    auto k = j;
    k["reg_info"]["ay"] = "56";
    const auto e = error_of(k.dump());
    EXPECT_NE(e.find("'reg_info.ay' must be an integer"), std::string::npos) << e;
  }
  {
    auto k = j;
    k["reg_info"]["ay"] = 1.5;
    EXPECT_NE(error_of(k.dump()).find("reg_info.ay"), std::string::npos);
  }
  {
    auto k = j;
    k["reg_info"]["zero_plane_info"].erase("reference_pixel_size");
    EXPECT_NE(error_of(k.dump()).find("'reg_info.zero_plane_info.reference_pixel_size' is missing"),
              std::string::npos);
  }
  {
    auto k = j;
    k["reg_info"]["zero_plane_info"]["reference_pixel_size"] = 0;
    EXPECT_NE(error_of(k.dump()).find("reference_pixel_size' must be > 0"), std::string::npos);
  }
  {
    auto k = j;
    k["reg_info"].erase("pad_info");
    EXPECT_NE(error_of(k.dump()).find("pad_info"), std::string::npos);
  }
  {
    auto k = j;
    k.erase("const_shift");
    EXPECT_NE(error_of(k.dump()).find("'const_shift' is missing"), std::string::npos);
  }
  {
    auto k = j;
    k["reg_info"]["bx"] = 1LL << 40;
    EXPECT_NE(error_of(k.dump()).find("does not fit in 32 bits"), std::string::npos);
  }
  EXPECT_NE(error_of("{not json").find("not valid JSON"), std::string::npos);
  EXPECT_NE(error_of("[1,2]").find("top level"), std::string::npos);
  EXPECT_NE(error_of("{}").find("'reg_info' is missing"), std::string::npos);
}

}  // namespace
}  // namespace fb
