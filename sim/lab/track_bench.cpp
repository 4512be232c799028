// facebooth-lab bench track: the tracker's per-frame cost on one core (ICP + weight solve, depth
// only, with landmark rows, and with dlib detection on the colour image) and the latency from
// frame arrival to the VMC datagrams leaving through a real loopback UDP socket. The take is
// rendered up front (synthetic_take.hpp). One JSON object on stdout, progress on stderr.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>

#include <algorithm>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "sim/lab/lab_commands.hpp"
#include "sim/scoring/take_runner.hpp"
#include "storage/asset_files.hpp"
#include "storage/durable_file.hpp"

namespace fb::cli {
namespace {

// A UDP socket bound to a free loopback port that nobody reads: the OSC datagrams of the
// latency figure leave through the real network stack to a real (if silent) destination.
class SinkSocket {
 public:
  SinkSocket() : fd_(::socket(AF_INET, SOCK_DGRAM, 0)) {
    if (!fd_.valid()) return;
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    addr.sin_port = 0;
    socklen_t len = sizeof(addr);
    if (::bind(fd_.get(), reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) != 0 ||
        ::getsockname(fd_.get(), reinterpret_cast<sockaddr*>(&addr), &len) != 0) {
      return;  // port() stays 0; the socket closes with fd_
    }
    port_ = ntohs(addr.sin_port);
  }
  int port() const { return port_; }

 private:
  UniqueFd fd_;
  int port_ = 0;
};

// What each figure of bench track measures.
nlohmann::json bench_track_setup() {
  return {
      {"ms_per_frame",
       "mean wall time of track() on steady-state frames: temporal smoothing "
       "(k = 5) + rigid ICP + blendshape solve, depth only"},
      {"calibration_ms",
       "the identity fit, once per subject on the frame that ends calibration (not in "
       "ms_per_frame): calibration_rounds Gauss-Newton rounds of the joint identity + pose fit "
       "over the stored frames, then one re-tracking of them"},
      {"ms_per_frame_with_landmarks",
       "the same plus dlib on the colour image (HOG detection in a window around the last "
       "face, 68-point shape prediction, mapping into the depth image) and the 51 landmark "
       "rows in the weight solve; dlib_ms_per_frame is the detection part alone"},
      {"ms_per_frame_landmark_rows",
       "tracker only, with ground-truth landmarks (+ 1.5 px noise) in the weight solve: the "
       "solve's landmark cost without detection"},
      {"ms_per_frame_with_landmarks_cpu", "thread CPU time of the dlib run (detection included)"},
      {"ms_per_frame_cpu",
       "thread CPU time of the same calls (the one-core cost even when other "
       "processes share the core; wall times include their preemption)"},
      {"latency_ms",
       "frame arrival (before detection and track()) -> the last VMC datagram handed to the "
       "kernel (lo_send_bundle returned), loopback UDP, with dlib landmarks"},
      {"frames", "pre-rendered synthetic take in memory (seed 7, sensor noise on)"}};
}

int run_bench_track(const ParsedOptions& options) {
  auto frames = options.get_int("frames");
  if (!frames || *frames < 60) return report_failure({"--frames must be an integer >= 60"});
  auto overrides = tracker_overrides(options.get("set"));
  if (!overrides) return report_failure(overrides.error());
  auto model_result = load_face_model();
  if (!model_result) return report_failure(model_result.error());
  const FaceModel& model = *model_result;
  auto mapping = make_arkit_mapping(model);
  if (!mapping) return report_failure(mapping.error());

  TakeSpec spec;
  spec.seed = 7;
  spec.frames = static_cast<int>(*frames);
  spec.color = true;
  std::cerr << "bench track: rendering " << spec.frames << " frames...\n";
  auto take = render_take(model, spec);
  if (!take) return report_failure(take.error());

  SinkSocket sink;
  if (sink.port() == 0) return report_failure({"bench track: cannot bind a loopback UDP socket"});
  VmcOptions vmc;
  vmc.port = sink.port();
  auto sender = VmcSender::open(vmc);
  if (!sender) return report_failure(sender.error());

  auto detector = load_landmark_detector(options.get("shape-predictor"));
  if (!detector) return report_failure(detector.error());
  TrackLandmarkSource dlib(std::move(*detector), take->calibration);

  nlohmann::json result;
  // Landmark modes: none (depth only), truth (landmark rows from ground truth + noise: the solve
  // cost without detection), dlib (detection + shape prediction + mapping on the colour image,
  // then the solve: the real per-frame cost with landmarks).
  for (const std::string mode : {"none", "truth", "dlib"}) {
    RunOptions run;
    run.tracker = *overrides;
    run.landmarks = mode == "truth";
    run.dlib = mode == "dlib" ? &dlib : nullptr;
    run.sender = sender->get();
    std::cerr << "bench track: tracking, landmarks: " << mode << "...\n";
    auto res = run_take(model, *mapping, *take, run);
    if (!res) return report_failure(res.error());
    // Steady state: tracked frames after calibration (no acquisition, no identity fit).
    std::vector<double> total, smooth, icp, weights, cpu, latency, landmark, with_detection;
    int detected = 0, steady = 0;
    double calibration_ms = 0;  // the one frame that fits the identity
    for (const auto& r : *res) {
      calibration_ms = std::max(calibration_ms, r.times.calibrate_ms);
      if (!r.calibrated || !tracked(r.state) || r.times.acquire_ms > 0 ||
          r.times.calibrate_ms > 0) {
        continue;
      }
      ++steady;
      detected += r.detected ? 1 : 0;
      total.push_back(r.times.total_ms());
      smooth.push_back(r.times.smooth_ms);
      icp.push_back(r.times.icp_ms);
      weights.push_back(r.times.weights_ms);
      cpu.push_back(r.cpu_ms);
      latency.push_back(r.latency_ms);
      landmark.push_back(r.landmark_ms);
      with_detection.push_back(r.times.total_ms() + r.landmark_ms);
    }
    const std::string key = mode == "none"    ? "without_landmarks"
                            : mode == "truth" ? "with_truth_landmarks"
                                              : "with_dlib_landmarks";
    const Summary total_s = stats_of(total), cpu_s = stats_of(cpu), latency_s = stats_of(latency);
    result[key] = {{"tracker_ms", to_json(total_s)},   {"smooth_ms", to_json(stats_of(smooth))},
                   {"icp_ms", to_json(stats_of(icp))}, {"weights_ms", to_json(stats_of(weights))},
                   {"thread_cpu_ms", to_json(cpu_s)},  {"latency_ms", to_json(latency_s)},
                   {"steady_frames", steady},          {"calibration_ms", calibration_ms}};
    if (mode == "none") {
      result["ms_per_frame"] = total_s.mean;
      result["calibration_ms"] = calibration_ms;
      result["ms_per_frame_cpu"] = cpu_s.mean;
      result["latency_ms_without_landmarks"] = latency_s.mean;
    } else if (mode == "truth") {
      result["ms_per_frame_landmark_rows"] = total_s.mean;
      result["latency_ms_truth_landmarks"] = latency_s.mean;
    } else {
      const Summary landmark_s = stats_of(landmark);
      result[key]["dlib_ms"] = to_json(landmark_s);
      result[key]["frames_with_detection"] = detected;
      result["ms_per_frame_with_landmarks"] = stats_of(with_detection).mean;
      result["ms_per_frame_with_landmarks_cpu"] = cpu_s.mean;
      result["dlib_ms_per_frame"] = landmark_s.mean;
      result["latency_ms"] = latency_s.mean;
      result["latency_ms_p95"] = latency_s.p95;
    }
  }
  auto tracker = FaceTracker::create(model, take->intrinsics, *overrides);
  result["samples"] = tracker ? (*tracker)->sample_count() : 0;
  result["tracker_overrides"] = options.get("set");
  result["shapes"] = model.fitting_expression_count;
  result["frames"] = spec.frames;
  result["threads"] = 1;
  result["setup"] = bench_track_setup();
  std::cout << result.dump(2) << std::endl;
  return kExitOk;
}

}  // namespace

Command bench_track_command() {
  return {{"bench track",
           "per-frame tracking cost (ICP + weight solve) and frame-to-OSC latency, one core",
           "Prints one JSON object: ms_per_frame (depth only), ms_per_frame_with_landmarks (dlib "
           "detection on the colour image included), latency_ms (frame arrival -> VMC datagrams "
           "sent on loopback) and the stage split.",
           {{"frames", "N", "frames of the synthetic take", "150"},
            {"shape-predictor", "PATH", "dlib 68-point model", kShapePredictor},
            {"set", "K=V,...", "tracker option overrides, as eval track takes them", ""},
            {"json", "", "print JSON (the only output format; accepted for symmetry)", ""}}},
          run_bench_track};
}

}  // namespace fb::cli
