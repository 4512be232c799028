// The booth's live stream carries the frame's wrinkle map weights (issue 40 item 5): a rig the
// host pushes with its detail captures (POST .../rig?detail=CAPTURE:EXPRESSION,...) is checked
// against the session and the booth's guide and stored with the rig; tracking with it puts
// "detail_weights" in /api/tracking/live and the SSE events, equal to what the host's
// DetailBlend::map_weights gives for the frame's weights. A rig without detail has none.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <thread>
#include <vector>

#include "algo/guide/guide_expressions.hpp"
#include "algo/tracking/arkit.hpp"
#include "algo/wrinkles/detail_blend.hpp"
#include "storage/asset_files.hpp"
#include "storage/export/facewarehouse.hpp"
#include "storage/session_store.hpp"
#include "tests/common/daemon_fixture.hpp"

// After every Eigen header (httplib's <resolv.h> defines _res).
#include <httplib.h>

namespace fb {
namespace {

class TrackingDetailTest : public test::DaemonFixture {
 protected:
  TrackingDetailTest() : DaemonFixture("fb-detail-test-", test::kThreeStepGuide) {}

  // A complete session of the three-step guide in the store (tiny captures: the upload needs
  // only the session's captures and their expressions). Returns its id.
  SessionId complete_session(const DaemonConfig& c) {
    auto store = SessionStore::open(c.storage.data_dir / "store");
    EXPECT_TRUE(store) << store.error().message;
    if (!store) return 0;
    const SubjectId subject = *store->add_subject("wrinkled");
    const SessionId session = *store->create_session(subject, {"neutral", "smile", "jaw_open"});
    for (int i = 0; i < 3; ++i) {
      CaptureInput input;
      RgbdFrame frame;
      frame.depth_mm.resize(4, 4);
      frame.raw_disparity.resize(4, 4);
      frame.color.resize(4, 4);
      input.frames.push_back(std::move(frame));
      EXPECT_TRUE(store->begin_capture(session, i));
      auto ok = store->commit_capture(session, i, std::move(input));
      EXPECT_TRUE(ok) << ok.error().message;
    }
    EXPECT_TRUE(store->session(session)->complete);
    return session;
  }

  // The model's own expressions as a rig (full positions), named by the model (no names=).
  static std::string model_rig_body(const FaceModel& model) {
    RigData rig;
    rig.neutral = model.neutral;
    for (int j = 0; j < model.expression_count; ++j) {
      const auto delta = model.expression_shape(j);
      std::vector<float> shape(model.neutral);
      for (std::size_t i = 0; i < shape.size(); ++i) shape[i] += delta[i];
      rig.shapes.push_back(std::move(shape));
    }
    const auto bs = encode_shape_bs(rig);
    return std::string(reinterpret_cast<const char*>(bs.data()), bs.size());
  }

  // Tracking mode until `frames` frames, then the latest live JSON with the face found.
  nlohmann::json track_live(Daemon& d, httplib::Client& http, int frames) {
    EXPECT_EQ(http.Post("/api/mode", R"({"mode": "tracking"})", "application/json")->status, 202);
    wait_for(d, [frames](auto& s) {
      return s["state"] == "tracking" && s["tracking"]["frames"].template get<int>() >= frames;
    });
    for (int i = 0; i < 100; ++i) {
      auto live = http.Get("/api/tracking/live");
      if (live && live->status == 200) {
        auto j = nlohmann::json::parse(live->body);
        if (j["face"].get<bool>()) return j;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    ADD_FAILURE() << "no tracked frame with the face";
    return {};
  }
  void stop_tracking(Daemon& d, httplib::Client& http) {
    EXPECT_EQ(http.Post("/api/mode", R"({"mode": "capture"})", "application/json")->status, 202);
    wait_for(d, [](auto& s) { return s["state"] == "idle"; });
  }
};

TEST_F(TrackingDetailTest, RigDetailCapturesGiveLiveMapWeightsAsTheHostComputesThem) {
  auto model = load_face_model();
  ASSERT_TRUE(model) << model.error().message;
  DaemonConfig c = config("synthetic:seed=4,identity=neutral,motion=static,expr=jawOpen:0.6");
  c.session.resume = false;
  const SessionId session = complete_session(c);
  ASSERT_GT(session, 0);
  auto d = make(c);
  ASSERT_TRUE(d);
  ASSERT_TRUE(d->start());
  httplib::Client http("127.0.0.1", d->http_port());
  const std::string rig_path = "/api/offload/sessions/" + std::to_string(session) + "/rig";
  const std::string body = model_rig_body(*model);

  // A bad detail list is refused with what is wrong and what to do; nothing is stored.
  struct Bad {
    const char* detail;
    int status;
    const char* says;
  };
  for (const Bad& bad :
       {Bad{"1:smile,9:frown", 422, "has captures 0..2"},
        Bad{"1:frown", 422, "recorded it as 'smile'"}, Bad{"0:neutral", 422, "is the neutral"},
        Bad{"smile", 400, "CAPTURE:EXPRESSION"}, Bad{"1:smile,1:smile", 400, "twice"},
        Bad{"1:sm%20ile", 400, "no usable expression name"}}) {
    auto res = http.Post(rig_path + "?detail=" + bad.detail, body, "application/octet-stream");
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, bad.status) << bad.detail << ": " << res->body;
    EXPECT_NE(res->body.find(bad.says), std::string::npos) << bad.detail << ": " << res->body;
  }
  auto ready = nlohmann::json::parse(http.Get("/api/offload/ready")->body);
  ASSERT_EQ(ready["sessions"].size(), 1u);
  EXPECT_EQ(ready["sessions"][0]["rigs"], 0) << ready.dump();

  auto up = http.Post(rig_path + "?detail=1:smile,2:jaw_open", body, "application/octet-stream");
  ASSERT_TRUE(up);
  ASSERT_EQ(up->status, 201) << up->body;
  const auto stored = nlohmann::json::parse(up->body);
  EXPECT_EQ(stored["detail_captures"].size(), 2u) << up->body;
  ready = nlohmann::json::parse(http.Get("/api/offload/ready")->body);
  EXPECT_EQ(ready["sessions"][0]["rig_detail_captures"],
            nlohmann::json::parse(
                R"([{"capture":1,"expression":"smile"},{"capture":2,"expression":"jaw_open"}])"));

  const auto frame = track_live(*d, http, 30);
  const auto status = d->status();
  EXPECT_NE(status["tracking"]["identity"].get<std::string>().find(
                "wrinkle map weights of 2 captures (smile@1, jaw_open@2)"),
            std::string::npos)
      << status.dump();
  ASSERT_TRUE(frame.contains("detail_weights")) << frame.dump();
  const auto& live = frame["detail_weights"];
  ASSERT_EQ(live.size(), 2u) << frame.dump();

  // The host's computation for the frame's weights: the guide's recipes over the model's fitting
  // shapes (as load_session_detail_blend makes them), a DetailBlend on small flat maps (the maps
  // do not enter c), the frame's ARKit weights back to the model's shapes.
  // The fixture guide's recipes (kThreeStepGuide) as the host's GuideSet holds them.
  GuideSet guide;
  guide.expressions = {{0, "neutral", "Neutral", {}},
                       {1, "smile", "Smile", {{"mouthSmile_L", 0.8f}, {"mouthSmile_R", 0.8f}}},
                       {2, "jaw_open", "Jaw open", {{"jawOpen", 0.6f}}}};
  std::vector<std::vector<float>> recipes;
  for (const char* name : {"smile", "jaw_open"}) {
    auto w = guide_weights(guide.expressions[static_cast<std::size_t>(guide.find(name))], *model);
    ASSERT_TRUE(w) << w.error().message;
    w->resize(static_cast<std::size_t>(model->fitting_expression_count));
    recipes.push_back(std::move(*w));
  }
  FloatImage disp;
  disp.resize(4, 4);
  ColorImage normal;
  normal.resize(4, 4);
  std::fill(normal.pixels.begin(), normal.pixels.end(), Rgb8{128, 128, 255});
  const std::vector<DetailLayerView> layers = {{&disp, &normal}, {&disp, &normal}};
  auto blend =
      DetailBlend::build({&disp, &normal}, layers, recipes, model->fitting_expression_count);
  ASSERT_TRUE(blend) << blend.error().message;
  auto mapping = make_arkit_mapping(*model);
  ASSERT_TRUE(mapping);
  std::array<float, kArkitShapeCount> arkit{};
  for (int k = 0; k < kArkitShapeCount; ++k)
    arkit[static_cast<std::size_t>(k)] = frame["weights"][kArkitNames[k]].get<float>();
  std::vector<float> a(static_cast<std::size_t>(model->fitting_expression_count));
  mapping->to_model(arkit, a);
  std::vector<float> host(2);
  blend->map_weights(a, host);
  const double smile = live["smile@1"].get<double>(), jaw = live["jaw_open@2"].get<double>();
  std::printf("live map weights smile@1 %.4f jaw_open@2 %.4f; host %.4f %.4f\n", smile, jaw,
              host[0], host[1]);
  // The live JSON's ARKit weights have 3 decimals (<= 0.0005 each, times |P| <= 1.7 here) and
  // the map weights 4.
  EXPECT_NEAR(smile, host[0], 2e-3);
  EXPECT_NEAR(jaw, host[1], 2e-3);
  // The subject holds jawOpen 0.6, the jaw_open recipe's own weight: about 1 on that capture,
  // about 0 on the smile.
  EXPECT_NEAR(jaw, 1.0, 0.35);
  EXPECT_NEAR(smile, 0.0, 0.2);

  // The event stream carries the same field.
  std::string event;
  http.Get("/api/tracking/events", [&](const char* data, size_t n) {
    event.append(data, n);
    return event.find("\n\n", event.find("event: face")) == std::string::npos;
  });
  EXPECT_NE(event.find("\"detail_weights\":{\"smile@1\":"), std::string::npos) << event;
  stop_tracking(*d, http);
  // Out of tracking the live frame is gone: the next run never serves this run's last frame.
  const auto after = http.Get("/api/tracking/live");
  ASSERT_TRUE(after);
  EXPECT_EQ(after->status, 404) << after->body;

  // A newer rig without detail: tracking streams no map weights.
  auto plain = http.Post(rig_path, body, "application/octet-stream");
  ASSERT_TRUE(plain);
  ASSERT_EQ(plain->status, 201) << plain->body;
  EXPECT_TRUE(nlohmann::json::parse(plain->body)["detail_captures"].empty());
  ready = nlohmann::json::parse(http.Get("/api/offload/ready")->body);
  EXPECT_TRUE(ready["sessions"][0]["rig_detail_captures"].empty()) << ready.dump();
  const auto without = track_live(*d, http, 10);
  EXPECT_FALSE(without.contains("detail_weights")) << without.dump();
  EXPECT_EQ(without["weights"].size(), 52u);
  stop_tracking(*d, http);
}

}  // namespace
}  // namespace fb
