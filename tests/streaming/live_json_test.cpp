#include "firmware/streaming/live_json.hpp"

#include <nlohmann/json.hpp>

#include <gtest/gtest.h>

#include "tests/common/allocation_counter.hpp"

namespace fb {
namespace {

TEST(LiveJson, SseEventCarriesTheFrameAsJson) {
  ArkitFrame frame;
  frame.index = 42;
  frame.time_s = 1.4;
  frame.face_found = true;
  frame.weights[17] = 0.5f;  // jawOpen
  frame.occluded = true;     // a hand in front of the face
  frame.occluded_fraction = 0.42f;
  const Eigen::Quaterniond flip(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()));
  frame.camera_from_model.rotation = flip * head_from_angles({0.1, 0.0, 0.0});
  frame.camera_from_model.translation = Eigen::Vector3d(1, 2, 700);
  std::string event;
  format_sse_event(frame, event);
  ASSERT_EQ(event.rfind("event: face\nid: 42\ndata: {", 0), 0u) << event;
  ASSERT_TRUE(event.ends_with("}\n\n"));
  const auto start = event.find("data: ") + 6;
  const auto json = nlohmann::json::parse(event.substr(start, event.size() - start - 2));
  EXPECT_EQ(json["frame"], 42);
  EXPECT_EQ(json["face"], true);
  EXPECT_EQ(json["occluded"], true);
  EXPECT_NEAR(json["hidden"].get<double>(), 0.42, 1e-9);
  EXPECT_NEAR(json["weights"]["jawOpen"].get<double>(), 0.5, 1e-9);
  EXPECT_EQ(json["weights"].size(), 52u);
  EXPECT_NEAR(json["head"]["yaw"].get<double>(), 0.1 * 180 / M_PI, 0.01);
  EXPECT_NEAR(json["head"]["z"].get<double>(), 700.0, 1e-9);
}

// With a rig's detail captures the frame ends with its wrinkle map weights, keyed
// EXPRESSION@CAPTURE; without them the field is absent. The string is reused: a second frame of
// the same size allocates nothing.
TEST(LiveJson, DetailWeightsFollowTheBlendshapeWeights) {
  ArkitFrame frame;
  frame.index = 7;
  frame.face_found = true;
  const std::vector<std::string> keys = {"smile@1", "jaw_open@2"};
  const std::vector<float> weights = {0.01234f, -0.5f};
  std::string out;
  format_frame_json(frame, out, {keys, weights});
  auto json = nlohmann::json::parse(out);
  ASSERT_TRUE(json.contains("detail_weights")) << out;
  EXPECT_NEAR(json["detail_weights"]["smile@1"].get<double>(), 0.0123, 1e-9);
  EXPECT_NEAR(json["detail_weights"]["jaw_open@2"].get<double>(), -0.5, 1e-9);
  EXPECT_EQ(json["weights"].size(), 52u);
  long allocations = 0;
  {
    test::CountThreadAllocations counter;
    format_frame_json(frame, out, {keys, weights});
    allocations = counter.count();
  }
  if (test::allocation_counting_available()) EXPECT_EQ(allocations, 0);
  std::string event;
  format_sse_event(frame, event, "face", {keys, weights});
  EXPECT_NE(event.find(R"("detail_weights":{"smile@1":0.0123,"jaw_open@2":-0.5000}})"),
            std::string::npos)
      << event;
  format_frame_json(frame, out);
  EXPECT_FALSE(nlohmann::json::parse(out).contains("detail_weights")) << out;
}

}  // namespace
}  // namespace fb
