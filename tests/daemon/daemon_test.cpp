#include <gtest/gtest.h>
#include <ifaddrs.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <arpa/inet.h>

#include <sys/socket.h>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <thread>
#include <vector>

#include "algo/core/figure_text.hpp"
#include "algo/fitting/face_fit.hpp"
#include "algo/landmarks/landmark_lifting.hpp"
#include "firmware/daemon/daemon.hpp"
#include "firmware/daemon/guide_steps.hpp"
#include "firmware/daemon/http_requests.hpp"
#include "firmware/daemon/session_machine.hpp"
#include "firmware/daemon/session_records.hpp"
#include "storage/asset_files.hpp"
#include "storage/export/facewarehouse.hpp"
#include "storage/session_store.hpp"
#include "tests/common/daemon_fixture.hpp"
#include "tests/fuzz/regression_input.hpp"

// After every Eigen header (httplib's <resolv.h> defines _res).
#include <httplib.h>

namespace fb {
namespace {

namespace fs = std::filesystem;
using std::chrono::milliseconds;

// ------------------------------------------------------------------ state machine

TEST(SessionMachine, HappyPathThroughTwoCaptures) {
  KioskState s = KioskState::kIdle;
  auto step = [&](KioskInput in, KioskAction expected_action, KioskState expected_state) {
    auto t = kiosk_transition(s, in);
    ASSERT_TRUE(t.has_value()) << to_string(s) << " + " << to_string(in);
    EXPECT_EQ(t->action, expected_action) << to_string(s) << " + " << to_string(in);
    EXPECT_EQ(t->next, expected_state);
    s = t->next;
  };
  step(KioskInput::kStart, KioskAction::kEnroll, KioskState::kEnrolled);
  step(KioskInput::kEnrolled, KioskAction::kShowGuide, KioskState::kGuide);
  step(KioskInput::kPress, KioskAction::kRecord, KioskState::kRecording);
  step(KioskInput::kTakeDone, KioskAction::kProcess, KioskState::kProcessing);
  step(KioskInput::kQaFailed, KioskAction::kNone, KioskState::kRetry);
  step(KioskInput::kPress, KioskAction::kRecord, KioskState::kRecording);
  step(KioskInput::kTakeDone, KioskAction::kProcess, KioskState::kProcessing);
  step(KioskInput::kQaPassed, KioskAction::kShowGuide, KioskState::kGuide);
  step(KioskInput::kPress, KioskAction::kRecord, KioskState::kRecording);
  step(KioskInput::kTakeDone, KioskAction::kProcess, KioskState::kProcessing);
  step(KioskInput::kLastDone, KioskAction::kFinish, KioskState::kComplete);
  step(KioskInput::kStart, KioskAction::kEnroll, KioskState::kEnrolled);
}

TEST(SessionMachine, CancelFromEverySessionStateGoesIdleAndAbandons) {
  for (auto s : {KioskState::kEnrolled, KioskState::kGuide, KioskState::kRecording,
                 KioskState::kProcessing, KioskState::kRetry}) {
    auto t = kiosk_transition(s, KioskInput::kCancel);
    ASSERT_TRUE(t) << to_string(s);
    EXPECT_EQ(t->next, KioskState::kIdle);
    EXPECT_EQ(t->action, KioskAction::kAbandon);
  }
}

TEST(SessionMachine, PressesThatMeanNothingAreIgnored) {
  EXPECT_FALSE(kiosk_transition(KioskState::kProcessing, KioskInput::kPress));
  EXPECT_FALSE(kiosk_transition(KioskState::kRecording, KioskInput::kPress));
  EXPECT_FALSE(kiosk_transition(KioskState::kRecording, KioskInput::kMode));  // no mode mid-take
  EXPECT_FALSE(kiosk_transition(KioskState::kIdle, KioskInput::kTakeDone));
}

TEST(SessionMachine, TrackingToggleAndErrors) {
  EXPECT_EQ(kiosk_transition(KioskState::kIdle, KioskInput::kMode)->next, KioskState::kTracking);
  EXPECT_EQ(kiosk_transition(KioskState::kTracking, KioskInput::kMode)->next, KioskState::kIdle);
  EXPECT_EQ(kiosk_transition(KioskState::kRecording, KioskInput::kFailed)->next,
            KioskState::kError);
  EXPECT_EQ(kiosk_transition(KioskState::kError, KioskInput::kPress)->next, KioskState::kIdle);
  EXPECT_EQ(kiosk_transition(KioskState::kIdle, KioskInput::kResume)->action,
            KioskAction::kResumeSession);
}

TEST(SessionMachine, ButtonsAndLeds) {
  EXPECT_EQ(input_for({ButtonId::kMain, PressKind::kShort}, KioskState::kGuide),
            KioskInput::kPress);
  EXPECT_EQ(input_for({ButtonId::kMain, PressKind::kLong}, KioskState::kGuide),
            KioskInput::kCancel);
  EXPECT_EQ(input_for({ButtonId::kMode, PressKind::kShort}, KioskState::kIdle), KioskInput::kMode);
  EXPECT_EQ(led_for(KioskState::kIdle), LedPattern::kReady);
  EXPECT_EQ(led_for(KioskState::kRecording), LedPattern::kRecording);
  EXPECT_EQ(led_for(KioskState::kProcessing), LedPattern::kProcessing);
  EXPECT_EQ(led_for(KioskState::kError), LedPattern::kError);
}

// ------------------------------------------------------------------ config

TEST(DaemonConfig, DefaultsAreValidAndRoundTrip) {
  DaemonConfig c = default_daemon_config();
  EXPECT_TRUE(validate_daemon_config(c));
  EXPECT_EQ(c.gpio.backend, "sim");
  EXPECT_EQ(c.camera.uri.rfind("synthetic:", 0), 0u);
  auto back = parse_daemon_config(to_toml(c), "roundtrip");
  ASSERT_TRUE(back) << back.error().message;
  EXPECT_EQ(back->camera.uri, c.camera.uri);
  EXPECT_EQ(back->http.port, c.http.port);
  EXPECT_EQ(back->storage.data_dir, c.storage.data_dir);
}

// Issue 35: toml++ printed min_fused_fraction = 0.59999999999999998. Floats print as written
// (shortest text) and still read back bit for bit, the defaults and awkward values alike.
TEST(DaemonConfig, FloatsPrintAsWrittenAndRoundTripExactly) {
  std::string printed;
  {
    std::unique_ptr<FILE, int (*)(FILE*)> pipe(
        ::popen(FB_FACEBOOTHD " --print-default-config", "r"), ::pclose);
    ASSERT_TRUE(pipe);
    char buf[4096];
    for (std::size_t n; (n = std::fread(buf, 1, sizeof buf, pipe.get())) > 0;)
      printed.append(buf, n);
  }
  EXPECT_NE(printed.find("\nmin_fused_fraction = 0.6\n"), std::string::npos) << printed;
  EXPECT_NE(printed.find("\nmax_fit_rms_mm = 1.5\n"), std::string::npos) << printed;
  EXPECT_NE(printed.find("\npreview_fps = 5.0\n"), std::string::npos) << printed;
  EXPECT_EQ(printed.find("99999"), std::string::npos) << printed;
  auto defaults = parse_daemon_config(printed, "printed");
  ASSERT_TRUE(defaults) << defaults.error().message;
  EXPECT_EQ(defaults->session.min_fused_fraction, 0.6);

  DaemonConfig c = default_daemon_config();
  double* floats[] = {&c.camera.preview_fps,
                      &c.camera.max_misregistration_px,
                      &c.session.min_coverage,
                      &c.session.max_residual_mm,
                      &c.session.min_fused_fraction,
                      &c.session.max_fit_rms_mm,
                      &c.session.max_landmark_error_mm,
                      &c.session.min_landmark_score};
  const double awkward[] = {0.1 + 0.2,          2.0 / 3.0,           1e-7,
                            19.999999999999996, 1.0 / 3.0,           1.4999999999999998,
                            5.000000000000001,  -0.30000000000000004};
  for (std::size_t i = 0; i < std::size(floats); ++i) *floats[i] = awkward[i];
  auto back = parse_daemon_config(to_toml(c), "roundtrip");
  ASSERT_TRUE(back) << back.error().message << "\n" << to_toml(c);
  DaemonConfig& b = *back;
  const double read[] = {b.camera.preview_fps,
                         b.camera.max_misregistration_px,
                         b.session.min_coverage,
                         b.session.max_residual_mm,
                         b.session.min_fused_fraction,
                         b.session.max_fit_rms_mm,
                         b.session.max_landmark_error_mm,
                         b.session.min_landmark_score};
  for (std::size_t i = 0; i < std::size(awkward); ++i)
    EXPECT_EQ(read[i], awkward[i]) << "float " << i << " in\n" << to_toml(c);
  EXPECT_NE(to_toml(c).find("min_coverage = 1e-07\n"), std::string::npos) << to_toml(c);
}

TEST(DaemonConfig, ReadsEverySection) {
  auto c = parse_daemon_config(R"(
[camera]
uri = "replay:/tmp/take"
capture_frames = 60
realtime = false
[gpio]
backend = "gpiod"
chip = "gpiochip4"
main_line = 5
led_line = -1
[storage]
data_dir = "data"
[http]
bind = "0.0.0.0"
port = 9000
token = "s3cret"
[session]
min_coverage = 0.4
[streaming]
osc_target = "127.0.0.1:39539"
)",
                               "test.toml", "/etc/facebooth");
  ASSERT_TRUE(c) << c.error().message;
  EXPECT_EQ(c->camera.uri, "replay:/tmp/take");
  EXPECT_EQ(c->camera.capture_frames, 60);
  EXPECT_FALSE(c->camera.realtime);
  EXPECT_EQ(c->gpio.backend, "gpiod");
  EXPECT_EQ(c->gpio.chip, "gpiochip4");
  EXPECT_EQ(c->gpio.main_line, 5);
  EXPECT_EQ(c->gpio.led_line, -1);
  EXPECT_EQ(c->storage.data_dir, fs::path("/etc/facebooth/data"));  // relative to the file
  EXPECT_EQ(c->http.port, 9000);
  EXPECT_EQ(c->http.token, "s3cret");
  EXPECT_DOUBLE_EQ(c->session.min_coverage, 0.4);
  EXPECT_EQ(c->streaming.osc_target, "127.0.0.1:39539");
}

TEST(DaemonConfig, ErrorsNameTheProblem) {
  auto typo = parse_daemon_config("[camera]\nurl = \"x\"\n", "a.toml");
  ASSERT_FALSE(typo);
  EXPECT_NE(typo.error().message.find("camera.url"), std::string::npos) << typo.error().message;
  auto type = parse_daemon_config("[http]\nport = \"eighty\"\n", "b.toml");
  ASSERT_FALSE(type);
  EXPECT_NE(type.error().message.find("http.port"), std::string::npos) << type.error().message;
  auto syntax = parse_daemon_config("[http\nport = 1\n", "c.toml");
  ASSERT_FALSE(syntax);
  EXPECT_NE(syntax.error().message.find("c.toml:1"), std::string::npos) << syntax.error().message;
  auto range = parse_daemon_config("[camera]\ncapture_frames = 2\n", "d.toml");
  ASSERT_FALSE(range);
  EXPECT_NE(range.error().message.find("capture_frames"), std::string::npos);
  auto section = parse_daemon_config("[cameras]\n", "e.toml");
  ASSERT_FALSE(section);
  EXPECT_NE(section.error().message.find("[cameras]"), std::string::npos);
  EXPECT_FALSE(load_daemon_config("/nonexistent/faceboothd.toml"));
}

// Found by daemon_config_fuzz: toml++ prints a string holding a newline as a multi-line literal
// string, whose first newline a reader drops, so uri = "\n" printed (--print-default-config)
// and read back as an empty uri. Strings are printed as escaped basic strings now.
TEST(DaemonConfig, PrintedStringsReadBackTheSame) {
  auto config = parse_daemon_config(
      test::fuzz_regression("daemon_config_fuzz", "uri-starting-with-newline"), "h.toml");
  ASSERT_TRUE(config) << config.error().message;
  EXPECT_EQ(config->camera.uri, "\n");
  config->http.token = std::string("a\"b\\c\x01\x7f'''d");
  auto again = parse_daemon_config(to_toml(*config), "printed.toml");
  ASSERT_TRUE(again) << again.error().message;
  EXPECT_EQ(again->camera.uri, "\n");
  EXPECT_EQ(again->http.token, config->http.token);
  EXPECT_EQ(to_toml(*again), to_toml(*config));
}

// Found by review of daemon_config_fuzz's reach: integers were narrowed to int unchecked (port
// 2^32 + 80 read as 80) and TOML's nan/inf passed the range checks (min_coverage = nan failed
// every capture's QA, and printed "nan").
TEST(DaemonConfig, RefusesOutOfRangeIntegersAndNonFiniteNumbers) {
  auto wide = parse_daemon_config("[http]\nport = 4294967376\n", "f.toml");
  ASSERT_FALSE(wide);
  EXPECT_NE(wide.error().message.find("http.port = 4294967376 is out of range"), std::string::npos)
      << wide.error().message;
  for (const char* text : {"[session]\nmin_coverage = nan\n", "[session]\nmax_residual_mm = inf\n",
                           "[camera]\npreview_fps = -nan\n"}) {
    auto r = parse_daemon_config(text, "g.toml");
    ASSERT_FALSE(r) << text;
    EXPECT_NE(r.error().message.find("must be a finite number"), std::string::npos)
        << r.error().message;
  }
}

// Found moving the request parsing out of the server for http_requests_fuzz: a member of the
// wrong type made nlohmann's value() throw (a 500 "internal error" for a client's mistake), and
// integer members were narrowed to int unchecked (index 2^32 + 2 read as 2, frames 2^32 + 45 as
// 45). Each input is kept in tests/fuzz/regressions/http_requests_fuzz/.
TEST(HttpRequests, WrongTypesAndWideIntegersAreClientErrors) {
  auto input = [](const char* name) {
    return test::fuzz_regression("http_requests_fuzz", name, /*skip_selector=*/true);
  };
  auto subject = parse_control_request(input("control-subject-not-a-string"));
  ASSERT_FALSE(subject);
  EXPECT_NE(subject.error().message.find("subject must be a string"), std::string::npos);
  auto button = parse_button_request(input("button-not-a-string"));
  ASSERT_FALSE(button);
  EXPECT_NE(button.error().message.find("button must be"), std::string::npos);
  auto corrections = parse_landmark_corrections(input("correction-index-wraps"));
  ASSERT_FALSE(corrections);
  EXPECT_NE(corrections.error().message.find("0..67"), std::string::npos);
  auto frames = parse_self_calibrate_request(input("self-calibrate-frames-wraps"), 45);
  ASSERT_FALSE(frames);
  EXPECT_NE(frames.error().message.find("10..300"), std::string::npos);
  // Found by http_requests_fuzz in the first version of the moved code: non-negative integers
  // are unsigned in nlohmann and that branch checked only the upper bound ({"frames": 1}).
  EXPECT_FALSE(parse_self_calibrate_request(input("self-calibrate-frames-below-10"), 45));
  // What the kiosk sends still parses.
  EXPECT_EQ(*parse_control_request(R"({"subject": "Ada"})"), "Ada");
  EXPECT_EQ(*parse_control_request(""), "");
  EXPECT_TRUE(*parse_mode_request(R"({"mode": "tracking"})"));
  EXPECT_EQ(*parse_self_calibrate_request("{}", 45), 45);
  auto ok = parse_landmark_corrections(R"({"corrections": [{"index": 67, "u": 1.5, "v": 2}]})");
  ASSERT_TRUE(ok);
  EXPECT_EQ(ok->at(0).index, 67);
  EXPECT_EQ(parse_path_id("000000000042").value(), 42);
  EXPECT_FALSE(parse_path_id("1234567890123"));
  EXPECT_EQ(parse_shape_names_param(",a,,b,").size(), 2u);
}

// Issue 35: no "nan" reaches a user. A missing figure (a fit that did not run, a mean over
// nothing) reads "n/a" in the daemon's log lines, QA reasons and `eval fit`'s console lines,
// and null in the status JSON, also for in-process readers (nlohmann keeps NaN until dump).
TEST(DaemonFigures, MissingFiguresAreNaInTextAndNullInJson) {
  EXPECT_EQ(figure_text(std::nan(""), 2), "n/a");
  EXPECT_EQ(figure_text(std::numeric_limits<double>::infinity(), 1), "n/a");
  EXPECT_EQ(figure_text(0.255, 1), "0.3");
  EXPECT_EQ(figure_text(1.0 / 3.0, 3), "0.333");
  EXPECT_TRUE(figure_json(std::nan("")).is_null());
  EXPECT_EQ(figure_json(0.5).get<double>(), 0.5);
  const nlohmann::json j = {{"fit_rms_mm", figure_json(std::nan(""))}};
  EXPECT_EQ(j.dump(), R"({"fit_rms_mm":null})");
}

TEST(GuideSteps, TheProjectGuideHasTwentyExpressions) {
  auto steps = load_guide_steps(fs::path(FB_DATA_DIR) / "guide_expressions.json");
  ASSERT_TRUE(steps) << steps.error().message;
  ASSERT_EQ(steps->size(), 20u);
  EXPECT_EQ((*steps)[0].name, "neutral");
  EXPECT_EQ((*steps)[0].synthetic_expr, "neutral");
  EXPECT_NE((*steps)[1].synthetic_expr.find("jawOpen:0.7"), std::string::npos);
  EXPECT_FALSE(parse_guide_steps("{\"expressions\": 3}"));
}

// Found while writing guide_fuzz (the target aborts on it): a label that is not a string made
// nlohmann's value() throw out of parse_guide_steps; faceboothd terminated on such a guide file.
TEST(GuideSteps, ALabelThatIsNotAStringIsAnError) {
  auto steps = parse_guide_steps(test::fuzz_regression("guide_fuzz", "label-not-a-string"));
  ASSERT_FALSE(steps);
  EXPECT_NE(steps.error().message.find("neutral.label is not a string"), std::string::npos)
      << steps.error().message;
}

// ------------------------------------------------------------------ daemon, end to end

// A temporary data directory and a short guide, so a whole session takes about a second.
class DaemonTest : public test::DaemonFixture {
 protected:
  DaemonTest() : DaemonFixture("fb-daemon-test-", test::kThreeStepGuide) {}

  // Tracking mode on a started daemon until `frames` frames are tracked; returns that status.
  nlohmann::json track_frames(Daemon& d, httplib::Client& http, int frames) {
    EXPECT_EQ(http.Post("/api/mode", R"({"mode": "tracking"})", "application/json")->status, 202);
    return wait_for(d, [frames](auto& s) {
      return s["state"] == "tracking" && s["tracking"]["frames"].template get<int>() >= frames;
    });
  }
  // Back to capture mode, then the take tracking stored, read from the store at `data_dir`.
  Result<TakeData> stop_and_read_take(Daemon& d, httplib::Client& http, const fs::path& data_dir) {
    EXPECT_EQ(http.Post("/api/mode", R"({"mode": "capture"})", "application/json")->status, 202);
    auto s =
        wait_for(d, [](auto& s) { return s["state"] == "idle" && s["tracking"]["last_take"] > 0; });
    StoreOptions ro;
    ro.read_only = true;
    auto store = SessionStore::open(data_dir / "store", ro);
    if (!store) return store.failure();
    return store->read_take(s["tracking"]["last_take"].get<std::int64_t>());
  }
};

// Check of a stored fit against stored data only: the stored mesh (model frame) placed with the
// stored fit pose onto the stored fused depth, scored with the fitting module's residual.
double stored_fit_rms_mm(const FaceModel& model, const CaptureData& capture, const MeshData& mesh) {
  const KinectCalibration calibration = KinectCalibration::defaults();  // the synthetic camera's
  FitTarget target;
  target.intrinsics = calibration.depth_intrinsics();
  target.depth_mm = depth_to_float(capture.fused_depth);
  std::vector<Eigen::Vector2d> color(capture.landmarks.size());
  for (std::size_t i = 0; i < color.size(); ++i)
    color[i] = {capture.landmarks[i].u, capture.landmarks[i].v};
  auto lifted = lift_landmarks(color, target.depth_mm, KinectRegistration(calibration));
  if (!lifted) return 1e9;
  target.landmarks = *lifted;
  if (!prepare_fit_target(target)) return 1e9;
  const auto& q = capture.info.qa_scores;
  if (!q.count("fit_pose_qw")) return 1e9;
  RigidPose pose;
  pose.translation = {q.at("fit_pose_tx"), q.at("fit_pose_ty"), q.at("fit_pose_tz")};
  pose.rotation = Eigen::Quaterniond(q.at("fit_pose_qw"), q.at("fit_pose_qx"), q.at("fit_pose_qy"),
                                     q.at("fit_pose_qz"));
  // rms_to_depth_mm_initial describes the start mesh, i.e. the stored one.
  RefineOptions once;
  once.iterations = 1;
  auto scored = refine_fit(model, target, mesh.positions, pose, once);
  if (!scored || scored->depth_correspondences < 1000) return 1e9;
  return scored->rms_to_depth_mm_initial;
}

TEST_F(DaemonTest, HeadlessSessionFitsStoresAndOffloads) {
  auto d = make(config());
  ASSERT_TRUE(d);
  auto r = d->run_headless_session("Ada");
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_EQ(r->captures_done, 3);
  EXPECT_EQ(r->frames_total, 24);
  const auto status = d->status();
  EXPECT_EQ(status["stages"]["quick_fit"], "on");
  EXPECT_GT(status["stages"]["landmark_model_load_ms"].get<double>(), 0.0);
  EXPECT_EQ(status["qa"]["landmarks"], "ok");
  EXPECT_EQ(status["qa"]["fit"], "expression");
  ASSERT_EQ(status["qa"]["capture"]["points"].size(), 68u);

  // The export bundle (storage/export's ExportFolder: manifest with checksums + session.json).
  EXPECT_TRUE(verify_export_folder(r->export_folder));
  std::ifstream in(r->export_folder / "session.json");
  auto doc = nlohmann::json::parse(in);
  EXPECT_TRUE(doc["complete"].get<bool>());
  EXPECT_EQ(doc["subject"], "Ada");
  EXPECT_EQ(doc["fitted_captures"], 3);
  ASSERT_EQ(doc["captures"].size(), 3u);
  for (const auto& c : doc["captures"]) {
    EXPECT_EQ(c["state"], "done");
    EXPECT_GT(c["qa"]["coverage"].get<double>(), 0.25);  // the face fills part of the box
    EXPECT_LT(c["qa"]["residual_mm"].get<double>(), 2.5);
    EXPECT_LT(c["qa"]["fit_rms_mm"].get<double>(), 1.5);
    EXPECT_GT(c["qa"]["landmarks_3d"].get<double>(), 30);
    for (const char* f : {"fused_depth", "color", "landmarks", "mesh"})
      EXPECT_TRUE(fs::exists(r->export_folder / c[f].get<std::string>())) << f;
  }

  // The store has landmarks and a fitted mesh per capture, and the meshes fit the stored depth.
  auto model = load_face_model();
  ASSERT_TRUE(model);
  StoreOptions ro;
  ro.read_only = true;
  auto store = SessionStore::open(r->store, ro);
  ASSERT_TRUE(store) << store.error().message;
  auto meshes = store->meshes(r->session_id);
  ASSERT_TRUE(meshes);
  ASSERT_EQ(meshes->size(), 3u);
  EXPECT_EQ((*meshes)[0].role, MeshRole::kNeutral);
  for (const auto& m : *meshes) {
    auto mesh = store->read_mesh(m.id);
    auto cap = store->read_capture(r->session_id, *m.capture_index);
    ASSERT_TRUE(mesh && cap);
    ASSERT_EQ(cap->landmarks.size(), 68u);
    const double rms = stored_fit_rms_mm(*model, *cap, *mesh);
    std::printf("capture %d (%s): stored mesh vs stored fused depth RMS %.2f mm\n",
                *m.capture_index, m.name.c_str(), rms);
    EXPECT_LT(rms, 1.5) << m.name;
  }

  // Offload: ready for rigging, the bundle, a rig back.
  httplib::Client http("127.0.0.1", d->http_port());
  http.set_read_timeout(60, 0);
  auto ready_res = http.Get("/api/offload/ready");
  ASSERT_TRUE(ready_res) << httplib::to_string(ready_res.error());
  auto ready = nlohmann::json::parse(ready_res->body);
  ASSERT_EQ(ready["sessions"].size(), 1u);
  EXPECT_TRUE(ready["sessions"][0]["ready_for_rigging"].get<bool>());
  EXPECT_EQ(ready["sessions"][0]["rigs"], 0);
  const std::string base = "/api/offload/sessions/" + std::to_string(r->session_id);
  auto tar = http.Get(base + "/bundle.tar");
  ASSERT_TRUE(tar);
  EXPECT_EQ(tar->status, 200);
  EXPECT_EQ(tar->body.substr(257, 5), "ustar");
  EXPECT_EQ(tar->body.size() % 512, 0u);
  EXPECT_NE(tar->body.find("session.json"), std::string::npos);
  EXPECT_NE(tar->body.find("mesh.obj"), std::string::npos);
  RigData rig;
  rig.neutral = model->neutral;
  for (int j = 0; j < 2; ++j) {
    auto shape = model->expression_shape(j);
    rig.shapes.emplace_back(shape.begin(), shape.end());
  }
  const auto bs = encode_shape_bs(rig);
  const std::string body(reinterpret_cast<const char*>(bs.data()), bs.size());
  auto up =
      http.Post(base + "/rig?names=eyeBlinkLeft,eyeBlinkRight", body, "application/octet-stream");
  ASSERT_TRUE(up);
  EXPECT_EQ(up->status, 201) << up->body;
  EXPECT_EQ(http.Post(base + "/rig", "garbage", "application/octet-stream")->status, 400);
  EXPECT_EQ(http.Post(base + "/rig?names=a", body, "application/octet-stream")->status, 422);
  EXPECT_EQ(http.Post("/api/offload/sessions/99/rig", body, "application/octet-stream")->status,
            404);
  EXPECT_EQ(http.Post("/api/session/start", std::string(100000, 'x'), "application/json")->status,
            413);
  ready = nlohmann::json::parse(http.Get("/api/offload/ready")->body);
  EXPECT_EQ(ready["sessions"][0]["rigs"], 1);
  // With a rig the export adds the FaceWarehouse layout (storage/export).
  EXPECT_EQ(http.Post("/api/sessions/" + std::to_string(r->session_id) + "/export", "{}",
                      "application/json")
                ->status,
            200);
  EXPECT_TRUE(fs::exists(r->export_folder.parent_path() /
                         ("session-" + std::to_string(r->session_id) + "-facewarehouse")));

  // Landmark correction of the last capture: the point moves, the store keeps the operator's
  // points and a new mesh, and the fit changes.
  const auto before = d->status()["qa"];
  const double u = before["capture"]["points"][33][0].get<double>() + 12.0;
  const double v = before["capture"]["points"][33][1].get<double>() + 6.0;
  nlohmann::json corr = {{"corrections", {{{"index", 33}, {"u", u}, {"v", v}}}}};
  const std::string path =
      "/api/sessions/" + std::to_string(r->session_id) + "/captures/2/landmarks";
  auto c = http.Post(path, corr.dump(), "application/json");
  ASSERT_TRUE(c);
  ASSERT_EQ(c->status, 200) << c->body;
  auto answer = nlohmann::json::parse(c->body);
  EXPECT_EQ(answer["qa"]["corrections"], 1);
  const auto after = d->status()["qa"];
  EXPECT_NEAR(after["capture"]["points"][33][0].get<double>(), u, 1e-6);
  EXPECT_TRUE(after["capture"]["corrected"][33].get<bool>());
  EXPECT_GT(after["capture"]["revision"].get<int>(), before["capture"]["revision"].get<int>());
  EXPECT_NE(after["landmark_error_mm"].get<double>(), before["landmark_error_mm"].get<double>());
  auto store2 = SessionStore::open(r->store, ro);
  ASSERT_TRUE(store2);
  auto corrected = store2->read_capture(r->session_id, 2);
  ASSERT_TRUE(corrected);
  EXPECT_EQ(corrected->landmark_source, LandmarkSource::kOperator);
  EXPECT_NEAR(corrected->landmarks[33].u, u, 1e-3);
  auto meshes2 = store2->meshes(r->session_id);
  ASSERT_EQ(meshes2->size(), 4u);
  auto m_old = store2->read_mesh((*meshes2)[2].id);
  auto m_new = store2->read_mesh((*meshes2)[3].id);
  double moved = 0;
  for (std::size_t i = 0; i < m_old->positions.size(); ++i)
    moved = std::max<double>(moved, std::abs(m_old->positions[i] - m_new->positions[i]));
  EXPECT_GT(moved, 0.01);  // the refit changed the mesh
  // Bad corrections are refused (an index outside 0..67 is a malformed body, 400, since the
  // parsing moved to http_requests; it was the fitter's 409 before); only the latest capture
  // can be corrected.
  EXPECT_EQ(
      http.Post(path, R"({"corrections": [{"index": 99, "u": 1, "v": 1}]})", "application/json")
          ->status,
      400);
  EXPECT_EQ(http.Post(path, R"({"corrections": "no"})", "application/json")->status, 400);
  EXPECT_EQ(http.Post("/api/sessions/" + std::to_string(r->session_id) + "/captures/0/landmarks",
                      corr.dump(), "application/json")
                ->status,
            409);

  // An export the daemon abandons because it is stopping leaves no folder, finished or not, and
  // says how to redo it; the same export without the stop request completes.
  d.reset();
  auto records = open_session_records(config().storage.data_dir);
  ASSERT_TRUE(records) << records.error().message;
  const fs::path exports = dir_ / "exports-stop";
  auto abandoned = (*records)->export_session(r->session_id, exports, [] { return true; });
  ASSERT_FALSE(abandoned);
  EXPECT_NE(abandoned.error().message.find("daemon is stopping"), std::string::npos)
      << abandoned.error().message;
  EXPECT_TRUE(!fs::exists(exports) || fs::is_empty(exports));
  auto done = (*records)->export_session(r->session_id, exports, [] { return false; });
  ASSERT_TRUE(done) << done.error().message;
  EXPECT_TRUE(verify_export_folder(*done));
}

// Tracking mode on the synthetic camera: the tracker runs with the session's neutral identity,
// VMC datagrams reach a UDP receiver, the page's live JSON has weights, and the take is stored.
TEST_F(DaemonTest, TrackingStreamsVmcAndStoresTheTake) {
  const int udp = ::socket(AF_INET, SOCK_DGRAM, 0);
  ASSERT_GE(udp, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t len = sizeof a;
  ASSERT_EQ(::bind(udp, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
  ASSERT_EQ(::getsockname(udp, reinterpret_cast<sockaddr*>(&a), &len), 0);
  timeval tv{2, 0};
  ::setsockopt(udp, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  DaemonConfig c = config();
  c.streaming.vmc_target = "127.0.0.1:" + std::to_string(ntohs(a.sin_port));
  auto d = make(c);
  ASSERT_TRUE(d);
  ASSERT_TRUE(d->start());
  httplib::Client http("127.0.0.1", d->http_port());
  auto s = track_frames(*d, http, 45);
  EXPECT_EQ(s["tracking"]["identity"].get<std::string>().rfind("mean face", 0), 0u);
  // Frame-to-datagram latency and the tracker's share are measured (bench daemon reports
  // them); the tracker's time is part of each frame's latency, so its median is no larger.
  const auto& latency = s["tracking"]["latency_ms"];
  EXPECT_GT(latency["median"].get<double>(), 0.0) << s.dump();
  EXPECT_GE(latency["p95"].get<double>(), latency["median"].get<double>());
  EXPECT_GT(s["tracking"]["track_ms_median"].get<double>(), 0.0);
  EXPECT_LE(s["tracking"]["track_ms_median"].get<double>(), latency["median"].get<double>());
  // The face was first found by detection (the tracker starts without one), guided the
  // identity calibration (10 frames), then was tracked on depth: a few detections, not one a
  // frame.
  EXPECT_EQ(s["tracking"]["reacquire"], "dlib face detection on the colour image, then depth");
  EXPECT_GE(s["tracking"]["detections"].get<int>(), 1) << s.dump();
  EXPECT_LT(s["tracking"]["detections"].get<int>(), 20) << s.dump();
  EXPECT_EQ(s["tracking"]["occluded"], false) << s.dump();  // nothing in front of the face
  EXPECT_EQ(s["tracking"]["occluded_frames"], 0) << s.dump();
  // Why the tracker has no face, when it has none (TrackReport::loss_reason): empty here.
  ASSERT_TRUE(s["tracking"].contains("reason")) << s.dump();
  if (s["tracking"]["state"] == "tracking") {
    EXPECT_EQ(s["tracking"]["reason"], "") << s.dump();
  }
  char buf[2048];
  const auto got = ::recv(udp, buf, sizeof buf, 0);
  ::close(udp);
  ASSERT_GT(got, 16);
  EXPECT_EQ(std::string(buf, 7), "#bundle");
  EXPECT_NE(std::string(buf, static_cast<std::size_t>(got)).find("/VMC/Ext/"), std::string::npos);
  auto live = http.Get("/api/tracking/live");
  ASSERT_TRUE(live);
  ASSERT_EQ(live->status, 200);
  auto frame = nlohmann::json::parse(live->body);
  EXPECT_TRUE(frame["face"].get<bool>()) << live->body;
  EXPECT_EQ(frame["weights"].size(), 52u);
  auto take = stop_and_read_take(*d, http, c.storage.data_dir);
  ASSERT_TRUE(take) << take.error().message;
  const TakeInfo& info = take->info;
  EXPECT_GE(info.frame_count, 45);
  EXPECT_EQ(info.shape_names.size(), 52u);
  EXPECT_EQ(take->values.size(), static_cast<std::size_t>(info.frame_count * info.stride()));
  // The head is about 700 mm in front of the camera in the synthetic scene.
  const float tz = take->frame(info.frame_count - 1)[2];
  EXPECT_NEAR(tz, 700.0f, 150.0f);
  // The take writer's layout: unit quaternions and frame times from the first frame, rising.
  for (int f = 0; f < info.frame_count; ++f) {
    const auto v = take->frame(f);
    EXPECT_NEAR(std::sqrt(v[3] * v[3] + v[4] * v[4] + v[5] * v[5] + v[6] * v[6]), 1.0, 1e-5);
  }
  EXPECT_DOUBLE_EQ(take->times_s.front(), 0.0);
  EXPECT_GT(take->times_s.back(), take->times_s.front());
}

// A hand passes in front of the face (the synthetic world's hand pass, frames 30-59 of the
// looping 90-frame take): the status says the face is occluded and how much of it is hidden,
// then that it is clear again, and the stored take's note counts the occluded frames.
TEST_F(DaemonTest, TrackingReportsAHandInFrontOfTheFace) {
  DaemonConfig c = config();
  c.camera.uri = "synthetic:seed=4,hand_pass=30";
  c.camera.realtime = true;  // 30 fps: the hand stays long enough to be seen in the status
  auto d = make(c);
  ASSERT_TRUE(d);
  ASSERT_TRUE(d->start());
  httplib::Client http("127.0.0.1", d->http_port());
  ASSERT_EQ(http.Post("/api/mode", R"({"mode": "tracking"})", "application/json")->status, 202);
  const auto occluded = wait_for(
      *d, [](auto& s) { return s["state"] == "tracking" && s["tracking"]["occluded"] == true; });
  EXPECT_GE(occluded["tracking"]["hidden_fraction"].get<double>(), 0.2) << occluded.dump();
  EXPECT_LE(occluded["tracking"]["hidden_fraction"].get<double>(), 1.0) << occluded.dump();
  const auto clear = wait_for(*d, [](auto& s) {
    return s["tracking"]["occluded"] == false && s["tracking"]["occluded_frames"] > 0;
  });
  const int frames = clear["tracking"]["occluded_frames"].get<int>();
  EXPECT_GE(frames, 5) << clear.dump();
  EXPECT_LE(frames, 30) << clear.dump();
  EXPECT_EQ(http.Post("/api/mode", R"({"mode": "capture"})", "application/json")->status, 202);
  const auto stored =
      wait_for(*d, [](auto& s) { return s["state"] == "idle" && s["tracking"]["last_take"] > 0; });
  const std::string note = stored["tracking"]["note"].get<std::string>();
  EXPECT_NE(note.find("the face was occluded on "), std::string::npos) << note;
  EXPECT_EQ(note.find("the face was occluded on 0)"), std::string::npos) << note;
}

// Tracking mode with a rig the host uploaded for the subject: the tracker uses the subject's
// own neutral and blendshapes (no calibration), as `facebooth track --rig-from-store` does. The
// synthetic subject (mean identity) holds jawOpen 0.6; the rig's jawOpen moves the face twice as
// far as the model's, so tracking with the rig reads about 0.3. A rig it cannot track is not
// used.
// A synthetic take (or a recording) ends; tracking mode starts it over and keeps tracking. The
// synthetic camera is started again rather than reopened (daemon.cpp, loop_preview_camera()).
TEST_F(DaemonTest, TrackingModeLoopsAnEndingTake) {
  DaemonConfig c = config();
  c.camera.uri = "synthetic:seed=4,frames=20";
  auto d = make(c);
  ASSERT_TRUE(d);
  ASSERT_TRUE(d->start());
  httplib::Client http("127.0.0.1", d->http_port());
  const auto s = track_frames(*d, http, 50);
  EXPECT_GE(s["tracking"]["frames"].get<int>(), 50) << s.dump();
  EXPECT_FALSE(s.contains("error")) << s.dump();
  auto take = stop_and_read_take(*d, http, c.storage.data_dir);
  ASSERT_TRUE(take) << take.error().message;
  EXPECT_GE(take->info.frame_count, 50);
}

TEST_F(DaemonTest, TrackingUsesTheSubjectsStoredRig) {
  auto model = load_face_model();
  ASSERT_TRUE(model);
  DaemonConfig c = config();
  c.camera.uri = "synthetic:seed=4,identity=neutral,motion=static,expr=jawOpen:0.6";
  c.session.resume = false;  // the session below is not finished: start idle, not in its guide
  RigId rig_id = 0;
  SubjectId subject = 0;
  SessionId session_id = 0;
  {
    auto store = SessionStore::open(c.storage.data_dir / "store");
    ASSERT_TRUE(store) << store.error().message;
    auto added = store->add_subject("rigged");
    ASSERT_TRUE(added);
    subject = *added;
    auto session = store->create_session(subject, {"neutral"});
    ASSERT_TRUE(session);
    session_id = *session;
    RigData rig;
    rig.neutral = model->neutral;
    rig.triangles = model->triangles;
    const int jaw = model->expression_index("jawOpen");
    ASSERT_GE(jaw, 0);
    const auto delta = model->expression_shape(jaw);  // the model's jawOpen delta
    std::vector<float> doubled(model->neutral);       // a rig keeps full positions
    for (std::size_t i = 0; i < doubled.size(); ++i) doubled[i] += 2.0f * delta[i];
    rig.shapes = {doubled, std::vector<float>(model->neutral)};
    rig.shape_names = {"jawOpen", "notAShape"};
    auto stored = store->add_rig(subject, *session, rig);
    ASSERT_TRUE(stored) << stored.error().message;
    rig_id = *stored;
  }
  auto d = make(c);
  ASSERT_TRUE(d);
  ASSERT_TRUE(d->start());
  httplib::Client http("127.0.0.1", d->http_port());
  const auto s = track_frames(*d, http, 30);
  EXPECT_EQ(s["tracking"]["identity"].get<std::string>(),
            "stored rig " + std::to_string(rig_id) + " of subject " + std::to_string(subject) +
                " (1 of its 2 shapes tracked)");
  auto take = stop_and_read_take(*d, http, c.storage.data_dir);
  ASSERT_TRUE(take) << take.error().message;
  const TakeInfo& info = take->info;
  // Tracked with the session's rig: the take records the session (issue 37).
  EXPECT_EQ(info.session, session_id);
  const auto name = std::find(info.shape_names.begin(), info.shape_names.end(), "jawOpen");
  ASSERT_NE(name, info.shape_names.end());
  const std::size_t column = 7 + static_cast<std::size_t>(name - info.shape_names.begin());
  double sum = 0;
  int n = 0;
  for (int f = 10; f < info.frame_count; ++f, ++n) sum += take->frame(f)[column];
  ASSERT_GT(n, 10);
  EXPECT_NEAR(sum / n, 0.3, 0.08) << "mean jawOpen over " << n << " frames";

  // A newer rig of the session with no shape the tracker knows is not used: tracking falls back
  // to calibrating (this store has no neutral fit) and the status says so.
  d.reset();
  {
    auto store = SessionStore::open(c.storage.data_dir / "store");
    ASSERT_TRUE(store) << store.error().message;
    RigData unknown;
    unknown.neutral = model->neutral;
    unknown.triangles = model->triangles;
    unknown.shapes = {model->neutral};
    unknown.shape_names = {"notAShape"};
    ASSERT_TRUE(store->add_rig(subject, session_id, unknown));
  }
  d = make(c);
  ASSERT_TRUE(d);
  ASSERT_TRUE(d->start());
  httplib::Client again("127.0.0.1", d->http_port());
  EXPECT_EQ(
      track_frames(*d, again, 5)["tracking"]["identity"].get<std::string>().rfind("mean face", 0),
      0u);
}

TEST_F(DaemonTest, CancelThenResumeAfterRestart) {
  const DaemonConfig c = config();
  std::int64_t session = 0;
  {
    auto d = make(c);
    ASSERT_TRUE(d);
    ASSERT_TRUE(d->start());
    d->post(KioskInput::kStart, "Grace");
    wait_for(*d, [](auto& s) { return s["state"] == "guide" && s["capture_index"] == 0; });
    ASSERT_TRUE(d->press({ButtonId::kMain, PressKind::kShort}));
    auto s = wait_for(*d, [](auto& s) { return s["state"] == "guide" && s["capture_index"] == 1; });
    session = s["session"];
    EXPECT_EQ(s["done_count"], 1);
    // A long press cancels: back to idle, the session stays incomplete.
    ASSERT_TRUE(d->press({ButtonId::kMain, PressKind::kLong}));
    wait_for(*d, [](auto& s) { return s["state"] == "idle"; });
  }  // "power loss": the daemon goes away with the session half done
  auto d = make(c);
  ASSERT_TRUE(d);
  ASSERT_TRUE(d->start());
  auto s = wait_for(*d, [](auto& s) { return s["state"] == "guide"; });
  EXPECT_TRUE(s["resumed"].get<bool>());
  EXPECT_EQ(s["session"], session);
  EXPECT_EQ(s["capture_index"], 1);  // the first capture is kept
  EXPECT_EQ(s["expression"]["name"], "smile");
  auto r = d->run_headless_session("unused");
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_EQ(r->session_id, session);
  EXPECT_EQ(r->captures_done, 3);
}

TEST_F(DaemonTest, FailedQualityCheckAsksForRetryAndCountsAttempts) {
  DaemonConfig c = config();
  c.session.min_coverage = 0.99;  // impossible: every take fails
  auto d = make(c);
  ASSERT_TRUE(d);
  ASSERT_TRUE(d->start());
  d->post(KioskInput::kStart, "Linus");
  wait_for(*d, [](auto& s) { return s["state"] == "guide"; });
  ASSERT_TRUE(d->press({ButtonId::kMain, PressKind::kShort}));
  auto s = wait_for(*d, [](auto& s) { return s["state"] == "retry"; });
  EXPECT_FALSE(s["qa"]["passed"].get<bool>());
  EXPECT_NE(s["qa"]["reason"].get<std::string>().find("coverage"), std::string::npos);
  EXPECT_EQ(s["led"], "error");
  ASSERT_TRUE(d->press({ButtonId::kMain, PressKind::kShort}));
  s = wait_for(*d, [](auto& s) { return s["state"] == "retry" && s["attempts"] == 2; });
  httplib::Client http("127.0.0.1", d->http_port());
  auto caps = nlohmann::json::parse(
      http.Get("/api/sessions/" + std::to_string(s["session"].get<int>()) + "/captures")->body);
  EXPECT_EQ(caps["captures"][0]["state"], "rejected");
  EXPECT_EQ(caps["captures"][0]["attempts"], 2);
  EXPECT_EQ(caps["captures"][1]["state"], "pending");
}

// Issue 35: headless retries printed only "processing --qa_failed--> retry"; the reason came
// only when the whole session failed. Now each failed check says why at once, in the log line
// of the transition and in the status that shows the retry screen.
TEST_F(DaemonTest, HeadlessRetriesPrintTheQaReasonAtOnce) {
  DaemonConfig c = config();
  c.session.min_coverage = 0.99;  // impossible: every take fails on coverage
  std::ofstream(dir_ / "faceboothd.toml") << to_toml(c);
  const std::string command =
      std::string(FB_FACEBOOTHD) + " --config " + (dir_ / "faceboothd.toml").string() +
      " --run-session-headless --subject Qa 2>" + (dir_ / "stderr.txt").string();
  const int rc = std::system(command.c_str());
  EXPECT_TRUE(WIFEXITED(rc) && WEXITSTATUS(rc) == 1) << rc;
  std::ifstream log(dir_ / "stderr.txt");
  std::vector<std::string> retries;
  int retry_lines_before_the_end = 0;
  bool ended = false;
  for (std::string line; std::getline(log, line);) {
    if (line.find("headless session failed") != std::string::npos) ended = true;
    if (line.find("--qa_failed--> retry") == std::string::npos) continue;
    retries.push_back(line);
    retry_lines_before_the_end += !ended;
  }
  EXPECT_TRUE(ended);
  ASSERT_EQ(retries.size(), 3u);  // the default three attempts
  EXPECT_EQ(retry_lines_before_the_end, 3);
  for (const auto& line : retries)
    EXPECT_NE(line.find("retry: face coverage "), std::string::npos) << line;

  c.storage.data_dir = dir_ / "in-process";  // not the headless run's unfinished session
  auto d = make(c);
  ASSERT_TRUE(d);
  ASSERT_TRUE(d->start());
  d->post(KioskInput::kStart, "Qa");
  wait_for(*d, [](auto& s) { return s["state"] == "guide"; });
  ASSERT_TRUE(d->press({ButtonId::kMain, PressKind::kShort}));
  auto s = wait_for(*d, [](auto& s) { return s["state"] == "retry"; });
  const std::string message = s["message"];
  EXPECT_NE(message.find("Quality check failed (face coverage "), std::string::npos) << message;
  EXPECT_EQ(s["last_input"], "qa_failed");
  std::printf("first retry line: %s\nstatus message: %s\n", retries.front().c_str(),
              message.c_str());
}

// A face high and off-centre with the chest and a desk nearer than it (the fixed kiosk box cut
// its forehead and let the chest take the volume): the take's face box comes from dlib on its
// first frame, every frame is fused, and the QA scores say how many fusion dropped.
TEST_F(DaemonTest, TakeFusesTheDetectedFaceWhereverItSits) {
  DaemonConfig c = config();
  c.camera.uri = "synthetic:seed=4,offset_x=70,offset_y=-95,torso=on,desk=on";
  c.camera.capture_frames = 12;
  auto d = make(c);
  ASSERT_TRUE(d);
  ASSERT_TRUE(d->start());
  d->post(KioskInput::kStart, "Grace");
  wait_for(*d, [](auto& s) { return s["state"] == "guide"; });
  ASSERT_TRUE(d->press({ButtonId::kMain, PressKind::kShort}));
  auto s = wait_for(*d, [](auto& s) {
    return s["state"] == "retry" || (s["state"] == "guide" && s["capture_index"] == 1);
  });
  httplib::Client http("127.0.0.1", d->http_port());
  auto caps = nlohmann::json::parse(
      http.Get("/api/sessions/" + std::to_string(s["session"].get<int>()) + "/captures")->body);
  const auto& qa = caps["captures"][0]["qa"];
  std::printf("take QA: %s\n", qa.dump().c_str());
  EXPECT_EQ(qa["face_box_detected"].get<double>(), 1.0);
  EXPECT_EQ(qa["frames_fused"].get<double>(), 12.0);
  EXPECT_EQ(qa["frames_fusion_dropped"].get<double>(), 0.0);
  EXPECT_GT(qa["coverage"].get<double>(), c.session.min_coverage);  // the face fills its box
  EXPECT_EQ(caps["captures"][0]["state"], "done") << s.dump();
}

TEST_F(DaemonTest, HttpControlsAndRejectsBadRequests) {
  auto d = make(config());
  ASSERT_TRUE(d);
  ASSERT_TRUE(d->start());
  httplib::Client http("127.0.0.1", d->http_port());
  auto status = http.Get("/api/status");
  ASSERT_TRUE(status);
  auto j = nlohmann::json::parse(status->body);
  EXPECT_EQ(j["state"], "idle");
  EXPECT_EQ(j["stages"]["landmarks"], "dlib 68-point");
  EXPECT_EQ(http.Get("/")->status, 200);
  EXPECT_NE(http.Get("/")->body.find("<html"), std::string::npos);
  // Nothing outside the routes, no traversal, ids are numbers.
  EXPECT_EQ(http.Get("/api/sessions/../../etc/passwd")->status, 404);
  EXPECT_EQ(http.Get("/api/sessions/abc")->status, 404);
  EXPECT_EQ(http.Get("/api/sessions/77")->status, 404);
  EXPECT_EQ(http.Get("/etc/passwd")->status, 404);
  EXPECT_EQ(http.Get("/api/guide/99.bmp")->status, 404);
  EXPECT_EQ(
      http.Post("/api/sim/button", R"({"button": "self-destruct"})", "application/json")->status,
      400);
  EXPECT_EQ(http.Post("/api/mode", "not json", "application/json")->status, 400);
  // The guide picture is a BMP of the face box.
  auto bmp = http.Get("/api/guide/1.bmp");
  ASSERT_TRUE(bmp);
  EXPECT_EQ(bmp->status, 200);
  EXPECT_EQ(bmp->body.substr(0, 2), "BM");
  // Mode switch through the page and back through the (simulated) mode button.
  EXPECT_EQ(http.Post("/api/mode", R"({"mode": "tracking"})", "application/json")->status, 202);
  wait_for(*d, [](auto& s) { return s["state"] == "tracking"; });
  EXPECT_EQ(http.Post("/api/sim/button", R"({"button": "mode"})", "application/json")->status, 202);
  wait_for(*d, [](auto& s) { return s["state"] == "idle"; });
  // Live events: the first SSE message is the status.
  std::string events;
  httplib::Client sse("127.0.0.1", d->http_port());
  sse.Get("/api/events", [&](const char* data, size_t n) {
    events.append(data, n);
    return events.find("\n\n") == std::string::npos;
  });
  EXPECT_EQ(events.rfind("event: status\ndata: {", 0), 0u) << events;
}

// The first non-loopback IPv4 address of this machine, if any.
std::string external_address() {
  ifaddrs* list = nullptr;
  if (getifaddrs(&list) != 0) return {};
  std::unique_ptr<ifaddrs, decltype(&freeifaddrs)> guard(list, &freeifaddrs);
  for (auto* a = list; a; a = a->ifa_next) {
    if (!a->ifa_addr || a->ifa_addr->sa_family != AF_INET) continue;
    char buf[INET_ADDRSTRLEN];
    inet_ntop(AF_INET, &reinterpret_cast<sockaddr_in*>(a->ifa_addr)->sin_addr, buf, sizeof buf);
    if (std::string(buf).rfind("127.", 0) != 0) return buf;
  }
  return {};
}

TEST_F(DaemonTest, SecondDaemonOnTheSamePortIsAClearError) {
  // httplib's default SO_REUSEPORT would let both bind and split the connections between them.
  auto first = make(config());
  ASSERT_TRUE(first);
  DaemonConfig c = config();
  c.http.port = first->http_port();
  c.storage.data_dir = dir_ / "data-second";
  DaemonOptions o;
  o.handle_signals = false;
  auto second = Daemon::create(c, o);
  ASSERT_FALSE(second) << "a second daemon bound port " << c.http.port;
  EXPECT_NE(second.error().message.find("in use"), std::string::npos) << second.error().message;
}

TEST_F(DaemonTest, NonLoopbackClientsNeedTheToken) {
  const std::string addr = external_address();
  if (addr.empty()) GTEST_SKIP() << "no non-loopback IPv4 address to test from";
  DaemonConfig c = config();
  c.http.bind = "0.0.0.0";
  c.http.token = "correct-horse";
  auto d = make(c);
  ASSERT_TRUE(d);
  ASSERT_TRUE(d->start());
  httplib::Client remote(addr, d->http_port());
  auto denied = remote.Get("/api/status");
  ASSERT_TRUE(denied);
  EXPECT_EQ(denied->status, 401);
  auto wrong = remote.Get("/api/status", {{"Authorization", "Bearer correct-horsf"}});
  EXPECT_EQ(wrong->status, 401);
  auto allowed = remote.Get("/api/status", {{"Authorization", "Bearer correct-horse"}});
  EXPECT_EQ(allowed->status, 200);
  httplib::Client local("127.0.0.1", d->http_port());
  EXPECT_EQ(local.Get("/api/status")->status, 200);
}

}  // namespace
}  // namespace fb
