// facebooth eval track | bench track | track: the real-time tracker (algo/tracking) scored on
// synthetic takes with ground truth, timed per frame and end to end (frame arrival -> OSC
// datagram sent), and run live on any camera with VMC/OSC streaming and Live Link CSV
// recording. One JSON object on stdout, progress on stderr.
//
// Synthetic takes (eval and bench): a random identity (N(0, 1) per mode), smooth random
// expression-weight tracks over a handful of shapes (smoothstep between random keyframes,
// neutral for the first frames so the tracker can calibrate the identity), smooth head motion
// (yaw/pitch/roll sinusoids and a few cm of translation), Kinect sensor noise on. 2D landmarks
// come from the ground truth plus Gaussian pixel noise, or (--landmarks dlib) from dlib on the
// synthetic colour render; the JSON says which. The occluder take composites a flat hand-sized
// plate into the scene and renders it through the Kinect sensor model (projector shadow, dropouts,
// noise).
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>
#include <cstdlib>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <numbers>
#include <numeric>
#include <optional>
#include <random>
#include <set>
#include <string_view>
#include <utility>

#include "algo/render/kinect_sensor.hpp"
#include "algo/tracking/arkit.hpp"
#include "algo/tracking/detected_landmarks.hpp"
#include "algo/tracking/face_tracker.hpp"
#include "drivers/camera/synthetic/synthetic_camera.hpp"
#include "firmware/streaming/live_json.hpp"
#include "firmware/streaming/vmc_sender.hpp"
#include "host/cli/commands.hpp"
#include "host/cli/frame_open.hpp"
#include "host/cli/progress.hpp"
#include "storage/asset_files.hpp"
#include "storage/export/livelink_csv.hpp"
#include "storage/session_store.hpp"

namespace fb::cli {
namespace {

using Clock = std::chrono::steady_clock;
constexpr double kDeg = 180.0 / std::numbers::pi;
constexpr double kLandmarkNoisePx = 1.5;
constexpr double kMisdetectionPx = 15.0;  // occluder take: landmarks under the plate move this far

double ms_between(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

double thread_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

constexpr const char* kShapePredictor = "/usr/share/dlib/shape_predictor_68_face_landmarks.dat";

// dlib's detector + 68-point predictor (Debian libdlib-data), ~1 s to deserialise.
Result<LandmarkDetector> load_landmark_detector(const std::string& option) {
  const std::filesystem::path path = option.empty() ? kShapePredictor : option;
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    return fail("cannot read the landmark model " + path.string() +
                " (install Debian's libdlib-data or pass --shape-predictor PATH)");
  }
  return LandmarkDetector::create(in);
}

struct Stats {
  double mean = 0, median = 0, p95 = 0, max = 0;
  int count = 0;
};
Stats stats_of(std::vector<double> v) {
  Stats s;
  if (v.empty()) return s;
  std::sort(v.begin(), v.end());
  s.count = static_cast<int>(v.size());
  s.mean = std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
  s.median = v[v.size() / 2];
  s.p95 = v[std::min(v.size() - 1, static_cast<std::size_t>(0.95 * static_cast<double>(v.size())))];
  s.max = v.back();
  return s;
}
nlohmann::json to_json(const Stats& s) {
  return {{"mean", s.mean}, {"median", s.median}, {"p95", s.p95}, {"max", s.max}, {"n", s.count}};
}

// ---------------------------------------------------------------------------------------------
// Synthetic takes.

struct TakeSpec {
  std::uint64_t seed = 1;
  int frames = 150;
  int active_shapes = 5;
  int neutral_frames = 20;  // calibration window + margin: the subject holds a neutral face
  bool occluder = false;
  bool noise = true;
  bool color = false;  // keep the colour images (for dlib landmarks; 0.9 MB a frame)
};

struct Take {
  SyntheticOptions options;
  std::vector<int> active;  // model shape indices with a non-zero track
  Eigen::Vector3d face_centre_model = Eigen::Vector3d::Zero();  // true identity, model frame
  // Occluder (camera frame): plate centre per frame (NaN = absent), size in mm.
  std::vector<Eigen::Vector3f> occluder_centre;
  float occluder_width = 90.0f, occluder_height = 110.0f;
  int occluder_first = -1, occluder_last = -1;  // frames with the plate over the face region
};

// The gaze shapes are not animated in the takes: eyeLook* turn the eyeballs, which are not in
// the skin mesh, and what they do to the lids eyeWide and eyeBlink also do, so the tracker
// holds them (TrackerOptions::hold_gaze_shapes). They are still scored (truth 0).
bool animatable(const std::string& name) {
  return !is_gaze_shape(name);
}

float smoothstep(float x) {
  return x * x * (3.0f - 2.0f * x);
}

Take make_take(const FaceModel& model, const TakeSpec& spec) {
  Take take;
  std::mt19937_64 rng(spec.seed * 7919 + 17);
  std::normal_distribution<float> normal(0.0f, 1.0f);
  std::uniform_real_distribution<float> uniform(0.0f, 1.0f);
  SyntheticOptions& o = take.options;
  o.seed = spec.seed;
  o.frame_count = spec.frames;
  o.sensor.depth_noise = spec.noise;
  std::vector<float> identity(static_cast<std::size_t>(model.identity_count));
  for (auto& c : identity) c = normal(rng);
  o.identity_coeffs = identity;

  // Active shapes: distinct, animatable, not both of a left/right-exclusive pair.
  const int k = model.fitting_expression_count;
  std::set<std::string> used_bases;
  while (static_cast<int>(take.active.size()) < spec.active_shapes) {
    const int j = static_cast<int>(uniform(rng) * static_cast<float>(k)) % k;
    const std::string& name = model.expression_names[static_cast<std::size_t>(j)];
    if (!animatable(name)) continue;
    if (std::find(take.active.begin(), take.active.end(), j) != take.active.end()) continue;
    // jawLeft/jawRight, mouthLeft/mouthRight oppose each other: keep one of each.
    std::string base = name;
    if (base.ends_with("Left")) base.resize(base.size() - 4);
    if (base.ends_with("Right")) base.resize(base.size() - 5);
    if ((base == "jaw" || base == "mouth") && (name != "jawOpen" && name != "jawForward")) {
      if (!used_bases.insert(base + "_side").second) continue;
    }
    take.active.push_back(j);
  }
  // Keyframes every 12-24 frames with targets in [0, 0.9] (a third of them 0), smoothstep between.
  o.expression_track.assign(static_cast<std::size_t>(spec.frames),
                            std::vector<float>(static_cast<std::size_t>(k), 0.0f));
  for (int j : take.active) {
    int f0 = spec.neutral_frames;
    float w0 = 0.0f;
    while (f0 < spec.frames) {
      const int f1 = f0 + 12 + static_cast<int>(uniform(rng) * 12.0f);
      const float w1 = uniform(rng) < 0.33f ? 0.0f : 0.15f + 0.75f * uniform(rng);
      for (int f = f0; f < std::min(f1, spec.frames); ++f) {
        const float s = smoothstep(static_cast<float>(f - f0) / static_cast<float>(f1 - f0));
        o.expression_track[static_cast<std::size_t>(f)][static_cast<std::size_t>(j)] =
            w0 + (w1 - w0) * s;
      }
      f0 = f1;
      w0 = w1;
    }
  }

  // Head motion: sinusoids with random phases; rotation about the model origin as in the
  // synthetic camera (camera_from_model = T * R_flip * Ry(yaw) Rx(pitch) Rz(roll)).
  std::vector<float> mesh(static_cast<std::size_t>(3 * model.vertex_count));
  model.evaluate(identity, {}, mesh);
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (auto v : model.landmark_vertices) {
    centroid += Eigen::Vector3d(mesh[3 * v], mesh[3 * v + 1], mesh[3 * v + 2]);
  }
  centroid /= 68.0;
  take.face_centre_model = centroid;
  const double phase[6] = {uniform(rng) * 6.28, uniform(rng) * 6.28, uniform(rng) * 6.28,
                           uniform(rng) * 6.28, uniform(rng) * 6.28, uniform(rng) * 6.28};
  const Eigen::Quaterniond flip(Eigen::AngleAxisd(std::numbers::pi, Eigen::Vector3d::UnitX()));
  constexpr double kDistance = 700.0;
  for (int f = 0; f < spec.frames; ++f) {
    const double t = f / 30.0, w = 2.0 * std::numbers::pi;
    const double yaw = 20.0 * std::sin(w * t / 4.0 + phase[0]);
    const double pitch = 10.0 * std::sin(w * t / 3.0 + phase[1]);
    const double roll = 5.0 * std::sin(w * t / 5.0 + phase[2]);
    const Eigen::Vector3d offset(20.0 * std::sin(w * t / 3.5 + phase[3]),
                                 10.0 * std::sin(w * t / 4.5 + phase[4]),
                                 30.0 * std::sin(w * t / 5.5 + phase[5]));
    RigidPose p;
    p.rotation = (flip * head_from_angles({yaw / kDeg, pitch / kDeg, roll / kDeg})).normalized();
    p.translation = Eigen::Vector3d(0, 0, kDistance) + offset - flip * centroid;
    o.camera_from_model_track.push_back(p);
  }

  if (spec.occluder) {
    // A 90 x 110 mm plate (a palm) 110 mm in front of the face, at mouth height, sweeping from
    // the subject's right to left across the lower face over 30 frames, starting at frame 60.
    const int start = std::min(60, spec.frames / 2), duration = 30;
    take.occluder_centre.assign(static_cast<std::size_t>(spec.frames),
                                Eigen::Vector3f::Constant(std::numeric_limits<float>::quiet_NaN()));
    for (int f = start; f < std::min(spec.frames, start + duration); ++f) {
      const RigidPose& p = o.camera_from_model_track[static_cast<std::size_t>(f)];
      // Mouth centre (landmarks 48-67) in the camera frame.
      Eigen::Vector3d mouth = Eigen::Vector3d::Zero();
      for (int l = 48; l < 68; ++l) {
        const auto v = model.landmark_vertices[static_cast<std::size_t>(l)];
        mouth += Eigen::Vector3d(mesh[3 * v], mesh[3 * v + 1], mesh[3 * v + 2]);
      }
      mouth = p.apply(mouth / 20.0);
      const double s = static_cast<double>(f - start) / (duration - 1);  // 0..1
      take.occluder_centre[static_cast<std::size_t>(f)] = Eigen::Vector3f(
          static_cast<float>(mouth.x() - 200.0 + 400.0 * s), static_cast<float>(mouth.y() + 5.0),
          static_cast<float>(mouth.z() - 110.0));
    }
  }
  return take;
}

// Re-renders a frame with the occluder plate through a second sensor model (the synthetic
// camera's own scene + the plate), and marks which pixels the plate changed.
class OccluderCompositor {
 public:
  explicit OccluderCompositor(const SyntheticOptions& o)
      : sensor_(KinectRegistration(o.calibration), o.sensor), background_(o.background_mm) {}

  Result<void> render(const SyntheticCamera& camera, const FrameTruth& truth,
                      const Eigen::Vector3f& centre, float width, float height, std::uint64_t seed,
                      RgbdFrame& frame, Image<std::uint8_t>& changed) {
    const auto model_vertices = camera.model_vertices();
    const auto model_triangles = camera.model_triangles();
    const Eigen::Matrix3f r = truth.camera_from_model.rotation.toRotationMatrix().cast<float>();
    const Eigen::Vector3f t = truth.camera_from_model.translation.cast<float>();
    vertices_.clear();
    for (const auto& v : model_vertices) vertices_.push_back(r * v + t);
    triangles_.assign(model_triangles.begin(), model_triangles.end());
    auto quad = [&](const Eigen::Vector3f& a, const Eigen::Vector3f& b, const Eigen::Vector3f& c,
                    const Eigen::Vector3f& d) {
      const auto base = static_cast<std::uint32_t>(vertices_.size());
      vertices_.insert(vertices_.end(), {a, b, c, d});
      // Counter-clockwise seen from the camera (-z): a b c, a c d with y down.
      for (std::uint32_t i : {0u, 2u, 1u, 0u, 3u, 2u}) triangles_.push_back(base + i);
    };
    if (background_ > 0.0) {
      const auto z = static_cast<float>(background_), half = 3.0f * z;
      quad({-half, -half, z}, {half, -half, z}, {half, half, z}, {-half, half, z});
    }
    const bool present = std::isfinite(centre.x());
    if (present) {
      const float hw = 0.5f * width, hh = 0.5f * height;
      quad(centre + Eigen::Vector3f(-hw, -hh, 0), centre + Eigen::Vector3f(hw, -hh, 0),
           centre + Eigen::Vector3f(hw, hh, 0), centre + Eigen::Vector3f(-hw, hh, 0));
    }
    if (auto captured = sensor_.capture(vertices_, triangles_, seed, out_); !captured) {
      return captured.failure();
    }
    const auto& reference = camera.sensor_frame();
    changed.resize(frame.depth_mm.width, frame.depth_mm.height);
    for (std::size_t i = 0; i < changed.pixels.size(); ++i) {
      // Covered by the plate, or in its projector shadow.
      const bool covered =
          out_.noiseless_depth_mm.pixels[i] > 0.0f &&
          out_.noiseless_depth_mm.pixels[i] < reference.noiseless_depth_mm.pixels[i] - 5.0f;
      const bool shadowed = (out_.invalid.pixels[i] & kSensorProjectorShadow) &&
                            !(reference.invalid.pixels[i] & kSensorProjectorShadow);
      changed.pixels[i] = present && (covered || shadowed) ? 1 : 0;
    }
    std::copy(out_.depth_mm.pixels.begin(), out_.depth_mm.pixels.end(),
              frame.depth_mm.pixels.begin());
    return success();
  }

 private:
  KinectSensorModel sensor_;
  double background_ = 0.0;
  SensorFrame out_;
  std::vector<Eigen::Vector3f> vertices_;
  std::vector<std::uint32_t> triangles_;
};

// One rendered frame held in memory (so rendering is never part of a timing).
struct TakeFrame {
  DepthImage depth;
  FrameTruth truth;
  std::vector<Eigen::Vector2f> landmarks;     // truth + noise, depth pixels
  int landmarks_misdetected = 0;              // under the occluder plate, moved onto it
  std::vector<std::uint8_t> occluded_shapes;  // per model shape: its region is under the plate
  bool occluder_on_face = false;
  ColorImage color;  // only when TakeSpec::color (dlib landmarks)
};

struct RenderedTake {
  Take take;
  PinholeIntrinsics intrinsics;
  KinectCalibration calibration;
  std::vector<TakeFrame> frames;
};

Result<RenderedTake> render_take(const FaceModel& model, const TakeSpec& spec) {
  RenderedTake out;
  out.take = make_take(model, spec);
  auto camera = make_synthetic_camera(model, out.take.options);
  if (!camera) return camera.failure();
  if (auto started = (*camera)->start(); !started) return started.failure();
  out.intrinsics = (*camera)->info().depth_intrinsics;
  out.calibration = (*camera)->info().calibration;
  std::unique_ptr<OccluderCompositor> compositor;
  if (spec.occluder) compositor = std::make_unique<OccluderCompositor>(out.take.options);
  std::mt19937_64 rng(spec.seed * 31 + 5);
  std::normal_distribution<float> noise(0.0f, static_cast<float>(kLandmarkNoisePx));
  RgbdFrame frame;
  Image<std::uint8_t> changed;
  const int k = model.fitting_expression_count;
  std::vector<float> mesh(static_cast<std::size_t>(3 * model.vertex_count));
  for (int f = 0; f < spec.frames; ++f) {
    auto status = (*camera)->next_frame(frame, std::chrono::milliseconds(1000));
    if (!status) return status.failure();
    if (*status != FrameStatus::kFrame) break;
    TakeFrame tf;
    const FrameTruth& truth = *(*camera)->truth();
    tf.occluded_shapes.assign(static_cast<std::size_t>(k), 0);
    if (compositor) {
      const auto& centre = out.take.occluder_centre[static_cast<std::size_t>(f)];
      if (auto r =
              compositor->render(**camera, truth, centre, out.take.occluder_width,
                                 out.take.occluder_height, spec.seed * 1000003 + f, frame, changed);
          !r) {
        return r.failure();
      }
      // A shape's region is occluded when > 2 % of its displacement lies on changed pixels.
      if (std::isfinite(centre.x())) {
        const Eigen::Matrix3d r = truth.camera_from_model.rotation.toRotationMatrix();
        const auto vertices = (*camera)->model_vertices();
        std::vector<std::uint8_t> hidden(static_cast<std::size_t>(model.face_vertex_count), 0);
        for (int v = 0; v < model.face_vertex_count; ++v) {
          const Eigen::Vector3d p = r * vertices[static_cast<std::size_t>(v)].cast<double>() +
                                    truth.camera_from_model.translation;
          const Eigen::Vector2d px = out.intrinsics.project(p);
          const int x = static_cast<int>(std::lround(px.x())),
                    y = static_cast<int>(std::lround(px.y()));
          // 3-pixel neighbourhood: the tracker's bilinear lookups and the face box margin.
          for (int dy = -3; dy <= 3 && !hidden[v]; ++dy) {
            for (int dx = -3; dx <= 3; ++dx) {
              if (changed.contains(x + dx, y + dy) && changed.at(x + dx, y + dy)) {
                hidden[static_cast<std::size_t>(v)] = 1;
                tf.occluder_on_face = true;
                break;
              }
            }
          }
        }
        for (int j = 0; j < k; ++j) {
          const auto shape = model.expression_shape(j);
          double total = 0, under = 0;
          for (int v = 0; v < model.face_vertex_count; ++v) {
            const double d =
                Eigen::Vector3d(shape[3 * v], shape[3 * v + 1], shape[3 * v + 2]).norm();
            total += d;
            if (hidden[static_cast<std::size_t>(v)]) under += d;
          }
          tf.occluded_shapes[static_cast<std::size_t>(j)] = total > 0 && under > 0.02 * total;
        }
      }
    }
    tf.depth = frame.depth_mm;
    if (spec.color) tf.color = frame.color;
    tf.truth = truth;
    tf.landmarks.resize(68);
    for (int l = 0; l < 68; ++l) {
      tf.landmarks[static_cast<std::size_t>(l)] =
          truth.landmarks_depth_px[static_cast<std::size_t>(l)].cast<float>() +
          Eigen::Vector2f(noise(rng), noise(rng));
    }
    if (compositor && tf.occluder_on_face) {
      // A detector's points under the plate land on the plate: all of them move together by
      // kMisdetectionPx in a random direction (the shape model keeps them in formation).
      const double angle = std::uniform_real_distribution<double>(0.0, 2.0 * M_PI)(rng);
      const Eigen::Vector2f shift(static_cast<float>(kMisdetectionPx * std::cos(angle)),
                                  static_cast<float>(kMisdetectionPx * std::sin(angle)));
      for (int l = 0; l < 68; ++l) {
        auto& px = tf.landmarks[static_cast<std::size_t>(l)];
        const int x = static_cast<int>(
                      std::lround(truth.landmarks_depth_px[static_cast<std::size_t>(l)].x())),
                  y = static_cast<int>(
                      std::lround(truth.landmarks_depth_px[static_cast<std::size_t>(l)].y()));
        bool under = false;
        for (int dy = -3; dy <= 3 && !under; ++dy)
          for (int dx = -3; dx <= 3 && !under; ++dx)
            under = changed.contains(x + dx, y + dy) && changed.at(x + dx, y + dy);
        if (under) {
          px += shift;
          ++tf.landmarks_misdetected;
        }
      }
    }
    out.frames.push_back(std::move(tf));
  }
  for (std::size_t f = 0; f < out.frames.size(); ++f) {
    if (out.frames[f].occluder_on_face) {
      if (out.take.occluder_first < 0) out.take.occluder_first = static_cast<int>(f);
      out.take.occluder_last = static_cast<int>(f);
    }
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// Running the tracker over a take.

struct FrameResult {
  TrackState state = TrackState::kSearching;
  bool calibrated = false;
  std::vector<float> abs_error;  // per model fitting shape
  double rotation_error_deg = 0, centre_error_mm = 0, origin_error_mm = 0;
  double raw_rotation_error_deg = 0, raw_centre_error_mm = 0;
  TrackTimes times;
  double cpu_ms = 0;       // thread CPU time of track()
  double latency_ms = -1;  // frame arrival -> OSC datagrams sent (when a sender is given)
  int landmarks_used = 0;
  double landmark_ms = 0;  // dlib detection + mapping (RunOptions::dlib), not in `times`
  // dlib's points against the truth (interior points 17-67 it placed): sum of squared per-axis
  // pixel errors and how many axes.
  double landmark_sq_error_px2 = 0;
  int landmark_axes = 0;
  bool detected = false;
  RigidPose estimate, truth;  // filtered estimate and truth (camera_from_model)
};

struct RunOptions {
  bool landmarks = true;
  TrackLandmarkSource* dlib = nullptr;  // landmarks from dlib on the colour images instead
  bool known_identity = false;          // load the true identity instead of calibrating
  VmcSender* sender = nullptr;
  std::vector<float>* identity_out = nullptr;  // the tracker's identity after the take
  TrackerOptions tracker;
};

RigidPose compose(const RigidPose& a, const RigidPose& b) {
  RigidPose p;
  p.rotation = (a.rotation * b.rotation).normalized();
  p.translation = a.rotation * b.translation + a.translation;
  return p;
}

double rotation_error_deg(const RigidPose& a, const RigidPose& b) {
  return Eigen::AngleAxisd(a.rotation.conjugate() * b.rotation).angle() * kDeg;
}

Result<std::vector<FrameResult>> run_take(const FaceModel& model, const ArkitMapping& mapping,
                                          const RenderedTake& take, const RunOptions& run) {
  auto tracker = FaceTracker::create(model, take.intrinsics, run.tracker);
  if (!tracker) return tracker.failure();
  if (run.known_identity && !take.frames.empty()) {
    if (auto r = (*tracker)->set_identity(take.frames[0].truth.identity_coeffs); !r) {
      return r.failure();
    }
  }
  const int k = model.fitting_expression_count;
  std::vector<FrameResult> results;
  results.reserve(take.frames.size());
  TrackReport report;
  ArkitFrame out;
  for (std::size_t f = 0; f < take.frames.size(); ++f) {
    const TakeFrame& tf = take.frames[f];
    TrackLandmarks landmarks{tf.landmarks, {}};
    const auto arrival = Clock::now();
    const double cpu0 = thread_cpu_ms();
    const TrackLandmarks* used = run.landmarks ? &landmarks : nullptr;
    FrameResult r;
    if (run.dlib != nullptr) {
      const LandmarkFrameResult found = run.dlib->detect(tf.color, tf.depth);
      used = run.dlib->landmarks();
      r.landmark_ms = found.ms;
      r.detected = found.found;
      if (used != nullptr) {
        for (std::size_t l = 17; l < 68; ++l) {
          if (!used->valid.empty() && !used->valid[l]) continue;
          const Eigen::Vector2f e = used->points[l] - tf.truth.landmarks_depth_px[l].cast<float>();
          r.landmark_sq_error_px2 += e.squaredNorm();
          r.landmark_axes += 2;
        }
      }
    }
    (*tracker)->track(tf.depth, static_cast<double>(f) / 30.0, used, report);
    const double cpu1 = thread_cpu_ms();
    if (run.sender) {
      out.index = f;
      out.time_s = static_cast<double>(f) / 30.0;
      out.face_found = report.face_found;
      out.camera_from_model = report.camera_from_model;
      mapping.to_arkit(std::span<const float>(report.weights.data(), static_cast<std::size_t>(k)),
                       out.weights);
      if (auto sent = run.sender->send(out); !sent) return sent.failure();
      r.latency_ms = ms_between(arrival, Clock::now());
    }
    r.state = report.state;
    r.calibrated = (*tracker)->calibrated();
    r.times = report.times;
    r.cpu_ms = cpu1 - cpu0;
    r.landmarks_used = report.landmarks_used;
    r.abs_error.resize(static_cast<std::size_t>(k));
    for (int j = 0; j < k; ++j) {
      const float truth = static_cast<std::size_t>(j) < tf.truth.expression_weights.size()
                              ? tf.truth.expression_weights[static_cast<std::size_t>(j)]
                              : 0.0f;
      r.abs_error[static_cast<std::size_t>(j)] =
          std::abs(report.weights[static_cast<std::size_t>(j)] - truth);
    }
    const RigidPose& truth_pose = tf.truth.camera_from_model;
    const Eigen::Vector3d c = take.take.face_centre_model;
    r.rotation_error_deg = rotation_error_deg(report.camera_from_model, truth_pose);
    r.centre_error_mm = (report.camera_from_model.apply(c) - truth_pose.apply(c)).norm();
    r.origin_error_mm = (report.camera_from_model.translation - truth_pose.translation).norm();
    r.raw_rotation_error_deg = rotation_error_deg(report.raw_camera_from_model, truth_pose);
    r.raw_centre_error_mm = (report.raw_camera_from_model.apply(c) - truth_pose.apply(c)).norm();
    r.estimate = report.camera_from_model;
    r.truth = truth_pose;
    results.push_back(std::move(r));
  }
  if (run.identity_out != nullptr) {
    const auto id = (*tracker)->identity();
    run.identity_out->assign(id.begin(), id.end());
  }
  return results;
}

// The rigid motion between two identities' neutral faces (model frame), least squares over the
// front-facing face vertices: how far the calibrated face's frame sits from the true one. Depth
// of the front of the face cannot tell this apart from a head pose (the gauge of the absolute
// pose), so it predicts the constant offset between estimated and true poses.
std::pair<double, double> identity_rigid_offset(const FaceModel& model,
                                                std::span<const float> truth,
                                                std::span<const float> estimate,
                                                const Eigen::Vector3d& centre) {
  std::vector<float> a(static_cast<std::size_t>(3 * model.vertex_count)), b(a.size());
  model.evaluate(truth, {}, a);
  model.evaluate(estimate, {}, b);
  std::vector<std::uint32_t> vertices;
  for (auto v : model.fitting_vertices) {
    if (static_cast<int>(v) < model.face_vertex_count && model.neutral[3 * v + 2] > 0.0f)
      vertices.push_back(v);
  }
  Eigen::Matrix3Xd src(3, vertices.size()), dst(3, vertices.size());
  for (std::size_t i = 0; i < vertices.size(); ++i) {
    const auto v = vertices[i];
    src.col(static_cast<Eigen::Index>(i)) = Eigen::Vector3d(a[3 * v], a[3 * v + 1], a[3 * v + 2]);
    dst.col(static_cast<Eigen::Index>(i)) = Eigen::Vector3d(b[3 * v], b[3 * v + 1], b[3 * v + 2]);
  }
  const Eigen::Matrix4d t = Eigen::umeyama(src, dst, false);
  const Eigen::Matrix3d r = t.topLeftCorner<3, 3>();
  const double angle = Eigen::AngleAxisd(r).angle() * kDeg;
  const double shift = (r * centre + t.topRightCorner<3, 1>() - centre).norm();
  return {angle, shift};
}

bool tracked(TrackState s) {
  return s == TrackState::kTracking || s == TrackState::kRecovered;
}

// The calibrated face's model frame differs from the true one by a constant rigid motion
// (the part of the identity that looks like a head rotation/translation, which depth of the
// front of the face cannot separate from the pose): Q = mean over tracked frames of
// T_true^-1 T_est. Pose errors are scored after it (gauge-free); absolute ones are reported too.
RigidPose calibration_gauge(const std::vector<FrameResult>& results) {
  Eigen::Vector4d qsum = Eigen::Vector4d::Zero();
  Eigen::Vector3d tsum = Eigen::Vector3d::Zero();
  int qn = 0;
  for (const auto& r : results) {
    if (!r.calibrated || r.state == TrackState::kCalibrating || !tracked(r.state)) continue;
    const RigidPose d = compose(r.truth.inverse(), r.estimate);
    Eigen::Vector4d q = d.rotation.coeffs();
    if (qn > 0 && q.dot(qsum) < 0) q = -q;
    qsum += q;
    tsum += d.translation;
    ++qn;
  }
  RigidPose gauge;
  if (qn > 0) {
    gauge.rotation.coeffs() = qsum.normalized();
    gauge.translation = tsum / qn;
  }
  return gauge;
}

// Scores the frames after calibration (the subject's identity is known from then on).
struct Score {
  std::vector<double> weight_error;  // per frame: mean over all shapes
  std::vector<double> active_error;  // per frame: mean over the take's active shapes
  std::vector<double> rot, centre, origin, raw_rot, raw_centre, abs_rot, abs_centre;
  std::vector<double> per_shape_sum;
  int frames = 0, lost = 0;
};

void score(const RenderedTake& take, const std::vector<FrameResult>& results, Score& s, int k) {
  if (s.per_shape_sum.empty()) s.per_shape_sum.assign(static_cast<std::size_t>(k), 0.0);
  const RigidPose gauge = calibration_gauge(results);
  for (const auto& r : results) {
    if (!r.calibrated || r.state == TrackState::kCalibrating) continue;
    ++s.frames;
    if (!tracked(r.state)) ++s.lost;
    double sum = 0;
    for (int j = 0; j < k; ++j) {
      sum += r.abs_error[static_cast<std::size_t>(j)];
      s.per_shape_sum[static_cast<std::size_t>(j)] += r.abs_error[static_cast<std::size_t>(j)];
    }
    s.weight_error.push_back(sum / k);
    double active = 0;
    for (int j : take.take.active) active += r.abs_error[static_cast<std::size_t>(j)];
    s.active_error.push_back(active / std::max<std::size_t>(1, take.take.active.size()));
    const RigidPose aligned = compose(r.truth, gauge);
    const Eigen::Vector3d c = take.take.face_centre_model;
    s.rot.push_back(rotation_error_deg(r.estimate, aligned));
    s.centre.push_back((r.estimate.apply(c) - aligned.apply(c)).norm());
    s.abs_rot.push_back(r.rotation_error_deg);
    s.abs_centre.push_back(r.centre_error_mm);
    s.origin.push_back(r.origin_error_mm);
    s.raw_rot.push_back(r.raw_rotation_error_deg);
    s.raw_centre.push_back(r.raw_centre_error_mm);
  }
}

nlohmann::json score_json(const Score& s, const FaceModel& model) {
  nlohmann::json j;
  j["frames_scored"] = s.frames;
  j["frames_lost"] = s.lost;
  j["weight_mae"] = stats_of(s.weight_error).mean;
  j["weight_mae_active_shapes"] = stats_of(s.active_error).mean;
  j["pose_error_deg"] = stats_of(s.rot).mean;
  j["pose_error_mm"] = stats_of(s.centre).mean;
  j["pose_error_deg_stats"] = to_json(stats_of(s.rot));
  j["pose_error_mm_stats"] = to_json(stats_of(s.centre));
  j["absolute_pose_error_deg"] = stats_of(s.abs_rot).mean;
  j["absolute_pose_error_mm"] = stats_of(s.abs_centre).mean;
  j["origin_error_mm_stats"] = to_json(stats_of(s.origin));
  j["raw_pose_error_deg"] = stats_of(s.raw_rot).mean;
  j["raw_pose_error_mm"] = stats_of(s.raw_centre).mean;
  nlohmann::json per_shape;
  for (std::size_t i = 0; i < s.per_shape_sum.size(); ++i) {
    per_shape[model.expression_names[i]] = s.frames ? s.per_shape_sum[i] / s.frames : 0.0;
  }
  j["per_shape_mae"] = per_shape;
  return j;
}

Result<const FaceModel*> shared_model() {
  static Result<FaceModel> model = load_face_model();
  if (!model) return model.failure();
  return &*model;
}

// ---------------------------------------------------------------------------------------------
// eval track

// `--set key=value,...` overrides of TrackerOptions for tuning runs (reported in the JSON).
// --set key=value[,key=value...]: tracker options by their TrackerOptions names (booleans as
// 0 / 1), for side-by-side runs of two option sets.
Result<TrackerOptions> tracker_overrides(const std::string& text) {
  using Setter = void (*)(TrackerOptions&, double);
  static constexpr std::pair<std::string_view, Setter> kSetters[] = {
      {"temporal_frames",
       [](TrackerOptions& o, double v) { o.temporal_frames = static_cast<int>(v); }},
      {"temporal_range_mm",
       [](TrackerOptions& o, double v) { o.temporal_range_mm = static_cast<float>(v); }},
      {"spatial_radius_px",
       [](TrackerOptions& o, double v) { o.spatial_radius_px = static_cast<int>(v); }},
      {"spatial_range_mm",
       [](TrackerOptions& o, double v) { o.spatial_range_mm = static_cast<float>(v); }},
      {"temporal_decay",
       [](TrackerOptions& o, double v) { o.temporal_decay = static_cast<float>(v); }},
      {"temporal_weight",
       [](TrackerOptions& o, double v) { o.temporal_weight = static_cast<float>(v); }},
      {"sparsity", [](TrackerOptions& o, double v) { o.sparsity = static_cast<float>(v); }},
      {"sparsity_signal_power",
       [](TrackerOptions& o, double v) { o.sparsity_signal_power = static_cast<float>(v); }},
      {"support_sparsity",
       [](TrackerOptions& o, double v) { o.support_sparsity = static_cast<float>(v); }},
      {"stale_temporal_floor",
       [](TrackerOptions& o, double v) { o.stale_temporal_floor = static_cast<float>(v); }},
      {"ridge", [](TrackerOptions& o, double v) { o.ridge = static_cast<float>(v); }},
      {"landmark_weight",
       [](TrackerOptions& o, double v) { o.landmark_weight = static_cast<float>(v); }},
      {"weight_iterations",
       [](TrackerOptions& o, double v) { o.weight_iterations = static_cast<int>(v); }},
      {"icp_gate_mm", [](TrackerOptions& o, double v) { o.icp_gate_mm = static_cast<float>(v); }},
      {"identity_prior",
       [](TrackerOptions& o, double v) { o.identity_prior = static_cast<float>(v); }},
      {"calibrate_depth_offsets",
       [](TrackerOptions& o, double v) { o.calibrate_depth_offsets = v != 0.0; }},
      {"max_depth_offset_mm",
       [](TrackerOptions& o, double v) { o.max_depth_offset_mm = static_cast<float>(v); }},
      {"antagonist_weight",
       [](TrackerOptions& o, double v) { o.antagonist_weight = static_cast<float>(v); }},
      {"calibration_frames",
       [](TrackerOptions& o, double v) { o.calibration_frames = static_cast<int>(v); }},
      {"calibration_rounds",
       [](TrackerOptions& o, double v) { o.calibration_rounds = static_cast<int>(v); }},
      {"level_gain", [](TrackerOptions& o, double v) { o.pose_filter.level_gain = v; }},
      {"trend_gain", [](TrackerOptions& o, double v) { o.pose_filter.trend_gain = v; }},
      {"rest_level_gain", [](TrackerOptions& o, double v) { o.pose_filter.rest_level_gain = v; }},
      {"sample_spacing_mm",
       [](TrackerOptions& o, double v) { o.sample_spacing_mm = static_cast<float>(v); }},
      {"extra_samples_per_shape",
       [](TrackerOptions& o, double v) { o.extra_samples_per_shape = static_cast<int>(v); }},
      {"hole_margin_mm",
       [](TrackerOptions& o, double v) { o.hole_margin_mm = static_cast<float>(v); }},
      {"hold_gaze_shapes", [](TrackerOptions& o, double v) { o.hold_gaze_shapes = v != 0; }},
      {"on_shape_sparsity",
       [](TrackerOptions& o, double v) { o.on_shape_sparsity = static_cast<float>(v); }},
      {"on_shape_min_weight",
       [](TrackerOptions& o, double v) { o.on_shape_min_weight = static_cast<float>(v); }},
      {"on_shape_max_signal",
       [](TrackerOptions& o, double v) { o.on_shape_max_signal = static_cast<float>(v); }},
      {"weak_shape_fraction",
       [](TrackerOptions& o, double v) { o.weak_shape_fraction = static_cast<float>(v); }},
      {"weak_shape_ridge",
       [](TrackerOptions& o, double v) { o.weak_shape_ridge = static_cast<float>(v); }},
      {"keep_identity_rigid",
       [](TrackerOptions& o, double v) { o.keep_identity_rigid = v != 0.0; }},
      {"weight_tukey_k",
       [](TrackerOptions& o, double v) { o.weight_tukey_k = static_cast<float>(v); }},
      {"weight_min_gate_mm",
       [](TrackerOptions& o, double v) { o.weight_min_gate_mm = static_cast<float>(v); }},
      {"calibrate_landmark_offsets",
       [](TrackerOptions& o, double v) { o.calibrate_landmark_offsets = v != 0.0; }},
      {"max_landmark_offset_mm",
       [](TrackerOptions& o, double v) { o.max_landmark_offset_mm = static_cast<float>(v); }},
      {"max_hidden_landmark_fraction",
       [](TrackerOptions& o, double v) { o.max_hidden_landmark_fraction = static_cast<float>(v); }},
      {"landmark_huber_px",
       [](TrackerOptions& o, double v) { o.landmark_huber_px = static_cast<float>(v); }},
      {"calibration_landmark_weight",
       [](TrackerOptions& o, double v) { o.calibration_landmark_weight = static_cast<float>(v); }},
      {"uncalibrated_max_rms_mm",
       [](TrackerOptions& o, double v) { o.uncalibrated_max_rms_mm = static_cast<float>(v); }},
      {"icp_iterations",
       [](TrackerOptions& o, double v) { o.icp_iterations = static_cast<int>(v); }},
      {"pose_refine_iterations",
       [](TrackerOptions& o, double v) { o.pose_refine_iterations = static_cast<int>(v); }},
      {"icp_converged_rad",
       [](TrackerOptions& o, double v) { o.icp_converged_rad = static_cast<float>(v); }},
      {"icp_converged_mm",
       [](TrackerOptions& o, double v) { o.icp_converged_mm = static_cast<float>(v); }},
      {"hidden_hold", [](TrackerOptions& o, double v) { o.hidden_hold = static_cast<float>(v); }},
      {"occluder_margin_mm",
       [](TrackerOptions& o, double v) { o.occluder_margin_mm = static_cast<float>(v); }},
      {"occluder_radius_px",
       [](TrackerOptions& o, double v) { o.occluder_radius_px = static_cast<int>(v); }},
  };
  TrackerOptions o;
  std::size_t start = 0;
  while (start < text.size()) {
    const auto comma = text.find(',', start);
    const std::string item =
        text.substr(start, comma == std::string::npos ? text.npos : comma - start);
    start = comma == std::string::npos ? text.size() : comma + 1;
    const auto eq = item.find('=');
    if (eq == std::string::npos) return fail("--set: expected key=value, got '" + item + "'");
    const std::string_view key = std::string_view(item).substr(0, eq);
    char* parsed_end = nullptr;
    const double v = std::strtod(item.c_str() + eq + 1, &parsed_end);
    if (parsed_end == item.c_str() + eq + 1 || *parsed_end != '\0')
      return fail("--set: '" + item + "' needs a number after '='");
    const auto* setter = std::find_if(std::begin(kSetters), std::end(kSetters),
                                      [&](const auto& s) { return s.first == key; });
    if (setter == std::end(kSetters)) {
      std::string known;
      for (const auto& s : kSetters) known += (known.empty() ? "" : ", ") + std::string(s.first);
      return fail("--set: unknown key '" + std::string(key) + "' (known: " + known + ")");
    }
    setter->second(o, v);
  }
  return o;
}

// One occluder take: a flat plate passes in front of the face. Landmarks are on: those under
// the plate are misdetected (moved onto it), as a real detector's would be, and the tracker
// must drop them itself. `run` gives the tracker options and whether the true identity is
// loaded instead of calibrated (both the take and its control). Appends the per-frame mean abs
// error of the shapes the plate does not cover to `unaffected`; returns the take's figures.
constexpr int kOccluderTakeFrames = 130;

Result<nlohmann::json> evaluate_occluder_take(const FaceModel& model, const ArkitMapping& mapping,
                                              const RunOptions& run, const TakeSpec& spec,
                                              std::vector<double>& unaffected) {
  const int k = model.fitting_expression_count;
  const std::uint64_t seed = spec.seed;
  TakeSpec ospec = spec;
  ospec.frames = kOccluderTakeFrames;
  ospec.occluder = true;
  ospec.color = false;
  std::cerr << "eval track: occluder take " << seed << ": rendering " << ospec.frames
            << " frames...\n";
  auto otake = render_take(model, ospec);
  if (!otake) return otake.failure();
  RunOptions orun = run;
  orun.landmarks = true;
  auto ores = run_take(model, mapping, *otake, orun);
  if (!ores) return ores.failure();
  // The control: the same take (motion, weights, landmark noise) without the plate, so the
  // plate's own effect on the shapes it does not cover can be told from how well those shapes
  // are tracked at all (a brow that moves while every landmark is dropped lags either way).
  TakeSpec cspec = ospec;
  cspec.occluder = false;
  std::cerr << "eval track: occluder take " << seed
            << ": rendering the control without the plate\n";
  auto ctake = render_take(model, cspec);
  if (!ctake) return ctake.failure();
  auto cres = run_take(model, mapping, *ctake, orun);
  if (!cres) return cres.failure();
  std::vector<double> added;  // per frame: unaffected error minus the control's on those shapes
  std::vector<double> occluded_err;
  const std::size_t first_frame = unaffected.size();
  nlohmann::json worst_unaffected = nlohmann::json::array();
  int lost_during = 0, misdetected = 0, used_during = 0;
  for (int f = otake->take.occluder_first; f >= 0 && f <= otake->take.occluder_last; ++f) {
    const auto& r = (*ores)[static_cast<std::size_t>(f)];
    const auto& tf = otake->frames[static_cast<std::size_t>(f)];
    if (!tracked(r.state)) ++lost_during;
    misdetected += tf.landmarks_misdetected;
    used_during += r.landmarks_used;
    const auto& control = (*cres)[static_cast<std::size_t>(f)];
    double sum = 0, osum = 0, csum = 0;
    int n = 0, on = 0;
    for (int j = 0; j < k; ++j) {
      if (tf.occluded_shapes[static_cast<std::size_t>(j)]) {
        osum += r.abs_error[static_cast<std::size_t>(j)];
        ++on;
      } else {
        sum += r.abs_error[static_cast<std::size_t>(j)];
        csum += control.abs_error[static_cast<std::size_t>(j)];
        ++n;
      }
    }
    if (n) unaffected.push_back(sum / n);  // the caller's, over all occluder takes
    if (n) added.push_back((sum - csum) / n);
    // The unoccluded shape with the largest error on this frame (diagnostics).
    int worst = -1;
    for (int j = 0; j < k; ++j) {
      if (tf.occluded_shapes[static_cast<std::size_t>(j)]) continue;
      if (worst < 0 ||
          r.abs_error[static_cast<std::size_t>(j)] > r.abs_error[static_cast<std::size_t>(worst)])
        worst = j;
    }
    if (worst >= 0) {
      worst_unaffected.push_back(
          {{"frame", f},
           {"unaffected_mae", n ? sum / n : 0.0},
           {"occluded_shapes", on},
           {"worst_shape", model.expression_names[static_cast<std::size_t>(worst)]},
           {"worst_error", r.abs_error[static_cast<std::size_t>(worst)]}});
    }
    if (on) occluded_err.push_back(osum / on);
  }
  // Recovery: frames after the plate leaves the face until the tracker is tracking again with
  // the weight error back at its pre-occlusion level (frame MAE <= max(0.05, 1.5 x the mean
  // before the plate)) and the pose within 1 deg / 2 mm of the truth (after the calibrated
  // frame's constant offset, see score()).
  int recovery = -1;
  if (otake->take.occluder_last >= 0) {
    double before = 0;
    int nb = 0;
    for (int f = 0; f < otake->take.occluder_first; ++f) {
      const auto& r = (*ores)[static_cast<std::size_t>(f)];
      if (!r.calibrated || r.state == TrackState::kCalibrating) continue;
      before += std::accumulate(r.abs_error.begin(), r.abs_error.end(), 0.0) / k;
      ++nb;
    }
    const double limit = std::max(0.05, 1.5 * (nb ? before / nb : 0.0));
    const RigidPose gauge = calibration_gauge(*ores);
    const Eigen::Vector3d c = otake->take.face_centre_model;
    for (int f = otake->take.occluder_last + 1; f < static_cast<int>(ores->size()); ++f) {
      const auto& r = (*ores)[static_cast<std::size_t>(f)];
      const double mae = std::accumulate(r.abs_error.begin(), r.abs_error.end(), 0.0) / k;
      const RigidPose aligned = compose(r.truth, gauge);
      if (tracked(r.state) && mae <= limit && rotation_error_deg(r.estimate, aligned) <= 1.0 &&
          (r.estimate.apply(c) - aligned.apply(c)).norm() <= 2.0) {
        recovery = f - otake->take.occluder_last - 1;
        break;
      }
    }
  }
  Score oscore;
  score(*otake, *ores, oscore, k);
  nlohmann::json active_names = nlohmann::json::array();
  for (int j : otake->take.active)
    active_names.push_back(model.expression_names[static_cast<std::size_t>(j)]);
  const std::vector<double> mine(unaffected.begin() + static_cast<std::ptrdiff_t>(first_frame),
                                 unaffected.end());
  std::cerr << "eval track: occluder take " << seed << ": unaffected weight error max "
            << stats_of(mine).max << ", recovery " << recovery << " frames\n";
  return nlohmann::json{
      {"seed", seed},
      {"active_shapes", active_names},
      {"frames_over_face", {otake->take.occluder_first, otake->take.occluder_last}},
      {"frames_lost_during_occlusion", lost_during},
      {"landmarks_misdetected", misdetected},
      {"landmarks_used_during_occlusion", used_during},
      {"occluded_unaffected_weight_error", stats_of(mine).max},
      {"unaffected_error_added_by_plate", stats_of(added).max},
      {"unaffected_error_added_by_plate_per_frame", to_json(stats_of(added))},
      {"unaffected_weight_error_per_frame", to_json(stats_of(mine))},
      {"occluded_shapes_weight_error_per_frame", to_json(stats_of(occluded_err))},
      {"occlusion_recovery_frames", recovery},
      {"per_frame", worst_unaffected},
      {"take", score_json(oscore, model)}};
}

int run_eval_track(const ParsedOptions& options) {
  auto overrides = tracker_overrides(options.get("set"));
  if (!overrides) return report_failure(overrides.error());
  auto seeds = options.get_int("seeds");
  auto frames = options.get_int("frames");
  auto active = options.get_int("active");
  auto occluder_seed = options.get_int("occluder-seed");
  auto occluder_takes_count = options.get_int("occluder-takes");
  if (!occluder_seed || *occluder_seed < 0 || !occluder_takes_count || *occluder_takes_count < 1)
    return report_failure(
        {"--occluder-seed must be a non-negative integer and --occluder-takes at least 1"});
  if (!seeds || !frames || !active)
    return report_failure({"--seeds, --frames, --active must be integers"});
  if (*seeds < 1 || *frames < 60 || *active < 1) {
    return report_failure({"need --seeds >= 1, --frames >= 60, --active >= 1"});
  }
  // The occluder takes' plate arrives at frame 60: the faces must move before it does.
  auto neutral = options.get_int("neutral-frames");
  if (!neutral || *neutral < 1 || *neutral > 50 || *neutral > *frames - 10) {
    return report_failure(
        {"--neutral-frames must be an integer from 1 to 50 and at most --frames - 10 (the "
         "takes' expressions start after it, and the occluder takes' plate arrives at frame 60)"});
  }
  const std::string occluder_identity = options.get("occluder-identity");
  if (occluder_identity != "calibrated" && occluder_identity != "known") {
    return report_failure(
        {"--occluder-identity must be calibrated (the tracker fits the subject, "
         "as on the device) or known (the true identity is loaded)"});
  }
  auto model_result = shared_model();
  if (!model_result) return report_failure(model_result.error());
  const FaceModel& model = **model_result;
  auto mapping = make_arkit_mapping(model);
  if (!mapping) return report_failure(mapping.error());
  const int k = model.fitting_expression_count;
  const std::string landmark_source = options.get("landmarks");
  if (landmark_source != "truth" && landmark_source != "dlib") {
    return report_failure({"--landmarks must be truth or dlib"});
  }
  std::optional<TrackLandmarkSource> dlib;
  long long dlib_frames = 0, dlib_found = 0, dlib_axes = 0;
  double dlib_sq_error = 0;

  // The take design both kinds of take share; each sets its seed (and the plain takes their
  // length, the occluder takes theirs).
  TakeSpec design;
  design.active_shapes = static_cast<int>(*active);
  design.neutral_frames = static_cast<int>(*neutral);

  Score with_landmarks, depth_only, known;
  nlohmann::json takes = nlohmann::json::array();
  PinholeIntrinsics intrinsics;
  for (long long seed = 1; seed <= *seeds; ++seed) {
    TakeSpec spec = design;
    spec.seed = static_cast<std::uint64_t>(seed);
    spec.frames = static_cast<int>(*frames);
    spec.color = landmark_source == "dlib";
    std::cerr << "eval track: seed " << seed << ": rendering " << spec.frames << " frames...\n";
    auto take = render_take(model, spec);
    if (!take) return report_failure(take.error());
    intrinsics = take->intrinsics;
    if (landmark_source == "dlib" && !dlib) {
      auto detector = load_landmark_detector(options.get("shape-predictor"));
      if (!detector) return report_failure(detector.error());
      dlib.emplace(std::move(*detector), take->calibration);
    }
    if (dlib) dlib->reset();
    RunOptions run;
    run.tracker = *overrides;
    run.landmarks = true;
    run.dlib = dlib ? &*dlib : nullptr;
    std::vector<float> calibrated_identity;
    run.identity_out = &calibrated_identity;
    auto a = run_take(model, *mapping, *take, run);
    if (!a) return report_failure(a.error());
    run.identity_out = nullptr;
    const auto [offset_deg, offset_mm] =
        identity_rigid_offset(model, take->frames[0].truth.identity_coeffs, calibrated_identity,
                              take->take.face_centre_model);
    const RigidPose gauge = calibration_gauge(*a);
    const double gauge_deg = Eigen::AngleAxisd(gauge.rotation).angle() * kDeg;
    const double gauge_mm =
        (gauge.apply(take->take.face_centre_model) - take->take.face_centre_model).norm();
    for (const auto& r : *a) {
      dlib_frames += dlib ? 1 : 0;
      dlib_found += r.detected ? 1 : 0;
      dlib_sq_error += r.landmark_sq_error_px2;
      dlib_axes += r.landmark_axes;
    }
    run.dlib = nullptr;
    run.landmarks = false;
    auto b = run_take(model, *mapping, *take, run);
    if (!b) return report_failure(b.error());
    run.landmarks = true;
    run.known_identity = true;
    auto c = run_take(model, *mapping, *take, run);
    if (!c) return report_failure(c.error());
    score(*take, *c, known, k);
    Score sa, sb;
    score(*take, *a, sa, k);
    score(*take, *b, sb, k);
    score(*take, *a, with_landmarks, k);
    score(*take, *b, depth_only, k);
    nlohmann::json active_names = nlohmann::json::array();
    for (int j : take->take.active)
      active_names.push_back(model.expression_names[static_cast<std::size_t>(j)]);
    takes.push_back({{"seed", seed},
                     {"active_shapes", active_names},
                     {"weight_mae", stats_of(sa.weight_error).mean},
                     {"weight_mae_active_shapes", stats_of(sa.active_error).mean},
                     {"pose_error_deg", stats_of(sa.rot).mean},
                     {"pose_error_mm", stats_of(sa.centre).mean},
                     {"absolute_pose_error_deg", stats_of(sa.abs_rot).mean},
                     {"absolute_pose_error_mm", stats_of(sa.abs_centre).mean},
                     {"constant_pose_offset_deg", gauge_deg},
                     {"constant_pose_offset_mm", gauge_mm},
                     {"identity_rigid_offset_deg", offset_deg},
                     {"identity_rigid_offset_mm", offset_mm},
                     {"frames_lost", sa.lost},
                     {"depth_only_weight_mae", stats_of(sb.weight_error).mean},
                     {"depth_only_pose_error_deg", stats_of(sb.rot).mean},
                     {"depth_only_pose_error_mm", stats_of(sb.centre).mean}});
    std::cerr << "eval track: seed " << seed << ": weight MAE " << stats_of(sa.weight_error).mean
              << " (depth only " << stats_of(sb.weight_error).mean << "), pose "
              << stats_of(sa.rot).mean << " deg " << stats_of(sa.centre).mean << " mm\n";
  }

  // Occluder takes (seeds occluder_seed ..): the figure is the worst frame of all of them.
  std::vector<double> unaffected;
  nlohmann::json occluder_takes = nlohmann::json::array();
  int recovery = 0;
  RunOptions occluder_run;
  occluder_run.tracker = *overrides;
  occluder_run.known_identity = occluder_identity == "known";
  for (long long i = 0; i < *occluder_takes_count; ++i) {
    TakeSpec ospec = design;
    ospec.seed = static_cast<std::uint64_t>(*occluder_seed + i);
    auto take = evaluate_occluder_take(model, *mapping, occluder_run, ospec, unaffected);
    if (!take) return report_failure(take.error());
    const int r = (*take)["occlusion_recovery_frames"];
    recovery = (r < 0 || recovery < 0) ? -1 : std::max(recovery, r);
    occluder_takes.push_back(std::move(*take));
  }

  nlohmann::json result;
  const nlohmann::json wl = score_json(with_landmarks, model);
  const nlohmann::json dl = score_json(depth_only, model);
  result["weight_mae"] = wl["weight_mae"];
  result["weight_mae_active_shapes"] = wl["weight_mae_active_shapes"];
  result["pose_error_deg"] = wl["pose_error_deg"];
  result["pose_error_mm"] = wl["pose_error_mm"];
  result["occluded_unaffected_weight_error"] = stats_of(unaffected).max;
  result["occluded_unaffected_weight_error_mean"] = stats_of(unaffected).mean;
  // The plate's own effect: the same error minus the control take's (no plate) on the same
  // shapes and frames, the worst frame of all takes.
  double added_max = -1.0;
  for (const auto& t : occluder_takes)
    added_max = std::max(added_max, t["unaffected_error_added_by_plate"].get<double>());
  result["occluded_unaffected_error_added_by_plate"] = added_max;
  result["occlusion_recovery_frames"] = recovery;
  result["absolute_pose_error_deg"] = wl["absolute_pose_error_deg"];
  result["absolute_pose_error_mm"] = wl["absolute_pose_error_mm"];
  result["with_landmarks"] = wl;
  result["known_identity"] = score_json(known, model);
  result["depth_only"] = dl;
  result["occluder"] = {
      {"takes", occluder_takes},
      {"frames_per_take", kOccluderTakeFrames},
      {"plate_mm", {90, 110}},
      {"plate_in_front_of_mouth_mm", 110},
      {"landmarks",
       "truth + 1.5 px noise; those under the plate misdetected (moved 15 px onto it)"},
      {"unaffected_weight_error_per_frame", to_json(stats_of(unaffected))}};
  {
    // The figure is the worst frame of a few takes, so how it spreads over takes says more
    // than one value (e.g. --occluder-seed 1010 --occluder-takes 20).
    std::vector<double> worst;
    for (const auto& t : occluder_takes)
      worst.push_back(t["occluded_unaffected_weight_error"].get<double>());
    result["occluder"]["worst_frame_per_take"] = to_json(stats_of(worst));
    result["occluder"]["takes_over_0_05"] =
        std::count_if(worst.begin(), worst.end(), [](double e) { return e > 0.05; });
  }
  result["takes"] = takes;
  result["tracker_overrides"] = options.get("set");
  result["landmark_source"] = landmark_source;
  if (dlib) {
    result["dlib_detection_rate"] = dlib_frames ? double(dlib_found) / dlib_frames : 0.0;
    result["dlib_landmark_error_px"] = dlib_axes ? std::sqrt(dlib_sq_error / dlib_axes) : 0.0;
  }
  if (auto t = FaceTracker::create(model, intrinsics, *overrides); t) {
    nlohmann::json weak = nlohmann::json::array();
    for (int j : (*t)->weak_shapes())
      weak.push_back(model.expression_names[static_cast<std::size_t>(j)]);
    result["weakly_observed_shapes"] = weak;
    result["samples"] = (*t)->sample_count();
  }
  result["setup"] = {
      {"seeds", *seeds},
      {"frames_per_take", *frames},
      {"active_shapes_per_take", *active},
      {"neutral_frames", *neutral},
      {"occluder_identity", occluder_identity},
      {"scored_frames", "after identity calibration (first 10 tracked frames, neutral face)"},
      {"weight_mae",
       "mean over frames of the mean abs error over all 53 model fitting shapes, "
       "with landmarks; weight_mae_active_shapes: over the animated shapes only"},
      {"pose_error_deg",
       "mean rotation error of the filtered (streamed) pose, after removing "
       "the constant rigid offset between the calibrated and the true model "
       "frame (an identity's rigid part, unobservable from depth; see "
       "absolute_pose_error_* and known_identity for absolute errors)"},
      {"pose_error_mm",
       "mean position error of the face centre (68-landmark centroid of the "
       "true identity), same alignment"},
      {"known_identity",
       "the same takes with the true identity loaded (set_identity) instead "
       "of calibrated: absolute pose errors are meaningful there"},
      {"landmarks",
       "--landmarks truth (default): ground-truth 2D landmarks + N(0, 1.5 px) noise; "
       "--landmarks dlib: dlib HOG + shape_predictor_68 on the synthetic colour render, "
       "mapped into the depth image (known_identity still uses truth); contour points 0-16 "
       "unused; dlib_landmark_error_px: its rms error per image axis against the truth"},
      {"head_motion",
       "yaw 20 deg, pitch 10 deg, roll 5 deg, 20/10/30 mm sinusoids, 3-5.5 s periods"},
      {"sensor", "Kinect v1 model, noise on, 700 mm"},
      {"occluded_unaffected_weight_error",
       "max over the frames of all occluder takes with the plate over the face of the mean "
       "abs error of the shapes whose region it does not cover (landmarks on, those under the "
       "plate misdetected)"},
      {"occluded_unaffected_error_added_by_plate",
       "the same, minus the error of the same shapes on the same frame of a control take "
       "(same seed, motion, weights, no plate): what the plate itself adds"},
      {"occlusion_recovery_frames",
       "frames after the plate leaves until tracking with every "
       "weight within 0.1 and pose within 1 deg / 2 mm (-1 = never)"}};
  std::cout << result.dump(2) << std::endl;
  return kExitOk;
}

// ---------------------------------------------------------------------------------------------
// bench track

// A UDP socket bound to a free loopback port that nobody reads: the OSC datagrams of the
// latency figure leave through the real network stack to a real (if silent) destination.
class SinkSocket {
 public:
  SinkSocket() {
    fd_ = ::socket(AF_INET, SOCK_DGRAM, 0);
    if (fd_ < 0) return;
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    addr.sin_port = 0;
    socklen_t len = sizeof(addr);
    if (::bind(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) != 0 ||
        ::getsockname(fd_, reinterpret_cast<sockaddr*>(&addr), &len) != 0) {
      ::close(fd_);
      fd_ = -1;
      return;
    }
    port_ = ntohs(addr.sin_port);
  }
  ~SinkSocket() {
    if (fd_ >= 0) ::close(fd_);
  }
  SinkSocket(const SinkSocket&) = delete;
  SinkSocket& operator=(const SinkSocket&) = delete;
  int port() const { return port_; }

 private:
  int fd_ = -1;
  int port_ = 0;
};

int run_bench_track(const ParsedOptions& options) {
  auto frames = options.get_int("frames");
  if (!frames || *frames < 60) return report_failure({"--frames must be an integer >= 60"});
  auto overrides = tracker_overrides(options.get("set"));
  if (!overrides) return report_failure(overrides.error());
  auto model_result = shared_model();
  if (!model_result) return report_failure(model_result.error());
  const FaceModel& model = **model_result;
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
    result[key] = {{"tracker_ms", to_json(stats_of(total))},
                   {"smooth_ms", to_json(stats_of(smooth))},
                   {"icp_ms", to_json(stats_of(icp))},
                   {"weights_ms", to_json(stats_of(weights))},
                   {"thread_cpu_ms", to_json(stats_of(cpu))},
                   {"latency_ms", to_json(stats_of(latency))},
                   {"steady_frames", steady},
                   {"calibration_ms", calibration_ms}};
    if (mode == "none") {
      result["ms_per_frame"] = stats_of(total).mean;
      result["calibration_ms"] = calibration_ms;
      result["ms_per_frame_cpu"] = stats_of(cpu).mean;
      result["latency_ms_without_landmarks"] = stats_of(latency).mean;
    } else if (mode == "truth") {
      result["ms_per_frame_landmark_rows"] = stats_of(total).mean;
      result["latency_ms_truth_landmarks"] = stats_of(latency).mean;
    } else {
      result[key]["dlib_ms"] = to_json(stats_of(landmark));
      result[key]["frames_with_detection"] = detected;
      result["ms_per_frame_with_landmarks"] = stats_of(with_detection).mean;
      result["ms_per_frame_with_landmarks_cpu"] = stats_of(cpu).mean;
      result["dlib_ms_per_frame"] = stats_of(landmark).mean;
      result["latency_ms"] = stats_of(latency).mean;
      result["latency_ms_p95"] = stats_of(latency).p95;
    }
  }
  auto tracker = FaceTracker::create(model, take->intrinsics, *overrides);
  result["samples"] = tracker ? (*tracker)->sample_count() : 0;
  result["tracker_overrides"] = options.get("set");
  result["shapes"] = model.fitting_expression_count;
  result["frames"] = spec.frames;
  result["threads"] = 1;
  result["setup"] = {
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
  std::cout << result.dump(2) << std::endl;
  return kExitOk;
}

// ---------------------------------------------------------------------------------------------
// track --camera URI

// The take layout in the session store (TakeInfo): per frame tx ty tz (mm) qx qy qz qw of the
// streamed camera_from_model pose, the 52 ARKit curves under their camelCase names, then one
// extra column "timestamp_s": the frame's camera time relative to the take's first frame (the
// store's TakeInfo has only a frame rate; the Live Link exporter ignores columns that are not
// ARKit curves, so it still reads the take).
constexpr const char* kTakeTimestampColumn = "timestamp_s";

std::vector<std::string> take_columns() {
  std::vector<std::string> names;
  for (auto name : kArkitNames) names.emplace_back(name);
  names.emplace_back(kTakeTimestampColumn);
  return names;
}

void append_take_frame(const ArkitFrame& frame, double take_start_s, std::vector<float>& values) {
  const RigidPose& p = frame.camera_from_model;
  const Eigen::Quaterniond q = p.rotation.normalized();
  const float pose[7] = {static_cast<float>(p.translation.x()),
                         static_cast<float>(p.translation.y()),
                         static_cast<float>(p.translation.z()),
                         static_cast<float>(q.x()),
                         static_cast<float>(q.y()),
                         static_cast<float>(q.z()),
                         static_cast<float>(q.w())};
  values.insert(values.end(), pose, pose + 7);
  values.insert(values.end(), frame.weights.begin(), frame.weights.end());
  values.push_back(static_cast<float>(frame.time_s - take_start_s));
}

// The subject's newest stored rig as a TrackerRig over the model's fitting shapes (matched by
// the model's expression names or the ARKit names of one-to-one curves). nullopt: no rig.
struct LoadedRig {
  RigId id = 0;
  RigData data;
  int matched = 0;
  TrackerRig view;
};
Result<std::optional<LoadedRig>> load_subject_rig(const SessionStore& store, SubjectId subject,
                                                  const FaceModel& model,
                                                  const ArkitMapping& mapping) {
  auto rigs = store.rigs(subject);
  if (!rigs) return rigs.failure();
  if (rigs->empty()) return std::optional<LoadedRig>{};
  LoadedRig out;
  out.id = rigs->front().id;  // newest first
  auto data = store.read_rig(out.id);
  if (!data) return data.failure();
  out.data = std::move(*data);
  if (out.data.vertex_count() != model.vertex_count) {
    return fail("rig " + std::to_string(out.id) + " of subject " + std::to_string(subject) +
                " has " + std::to_string(out.data.vertex_count()) + " vertices, the face model " +
                std::to_string(model.vertex_count) +
                "; the tracker needs a rig in the face model's topology (drop --rig-from-store "
                "to calibrate the identity instead)");
  }
  out.view.neutral = out.data.neutral;
  for (int s = 0; s < out.data.shape_count(); ++s) {
    const std::string& name = out.data.shape_names[static_cast<std::size_t>(s)];
    int index = model.expression_index(name);
    if (index < 0) {
      for (int a = 0; a < kArkitShapeCount; ++a) {
        const auto& src = mapping.sources[static_cast<std::size_t>(a)];
        if ((kArkitNames[a] == name || kLiveLinkNames[a] == name) && src[0] >= 0 && src[1] < 0) {
          index = src[0];
        }
      }
    }
    if (index < 0 || index >= model.fitting_expression_count) continue;
    out.view.shapes.emplace_back(index, out.data.shapes[static_cast<std::size_t>(s)]);
    ++out.matched;
  }
  return std::optional<LoadedRig>(std::move(out));
}

int run_track(const ParsedOptions& options) {
  const std::string uri = options.get("camera");
  if (uri.empty())
    return report_failure({"--camera URI is required (see `facebooth camera list`)"});
  auto max_frames = options.get_int("frames");
  if (!max_frames) return report_failure(max_frames.error());
  auto calibration = options.get_int("calibration-frames");
  if (!calibration || *calibration < 1)
    return report_failure({"--calibration-frames must be >= 1"});
  const std::string landmark_source = options.get("landmarks");
  if (landmark_source != "truth" && landmark_source != "none" && landmark_source != "dlib") {
    return report_failure({"--landmarks must be dlib, truth or none"});
  }
  const std::string reacquire = options.get("reacquire");
  if (reacquire != "dlib" && reacquire != "depth") {
    return report_failure({"--reacquire must be dlib or depth"});
  }
  auto model_result = shared_model();
  if (!model_result) return report_failure(model_result.error());
  const FaceModel& model = **model_result;
  auto mapping = make_arkit_mapping(model);
  if (!mapping) return report_failure(mapping.error());

  // Storage: takes go to --store (a new subject unless --subject names one); --rig-from-store
  // tracks with the subject's newest stored rig instead of calibrating an identity.
  const std::string store_path = options.get("store");
  const bool rig_from_store = options.flag("rig-from-store");
  std::optional<SessionStore> store;
  std::optional<SubjectId> subject;
  if (!options.get("subject").empty()) {
    auto id = options.get_int("subject");
    if (!id || *id <= 0)
      return report_failure({"--subject must be a subject id (see `facebooth store info`)"});
    subject = *id;
  }
  if ((subject || rig_from_store) && store_path.empty()) {
    return report_failure({"--subject and --rig-from-store need --store DIR"});
  }
  if (rig_from_store && !subject) {
    return report_failure({"--rig-from-store needs --subject ID (whose rig to load)"});
  }
  if (!store_path.empty()) {
    auto opened = SessionStore::open(store_path);
    if (!opened) return report_failure(opened.error());
    store.emplace(std::move(*opened));
    if (subject) {
      if (auto known = store->subject(*subject); !known) {
        return report_failure({"there is no subject " + std::to_string(*subject) + " in " +
                               store_path + " (see `facebooth store info --store " + store_path +
                               "`), or omit --subject to record under a new subject"});
      }
    }
  }
  std::optional<LoadedRig> rig;
  if (rig_from_store) {
    auto loaded = load_subject_rig(*store, *subject, model, *mapping);
    if (!loaded) return report_failure(loaded.error());
    rig = std::move(*loaded);
  }

  auto camera = open_started_camera(uri);
  if (!camera) return report_failure(camera.error());
  const CameraInfo info = (*camera)->info();
  TrackerOptions tracker_options;
  tracker_options.calibration_frames = static_cast<int>(*calibration);
  auto tracker = FaceTracker::create(model, info.depth_intrinsics, tracker_options);
  if (!tracker) return report_failure(tracker.error());
  std::string subject_model = "identity calibrated on the first frames";
  if (rig) {
    if (auto r = (*tracker)->set_rig(rig->view); !r) return report_failure(r.error());
    subject_model =
        "stored rig " + std::to_string(rig->id) + " (" + std::to_string(rig->matched) + " shapes)";
  } else if (rig_from_store) {
    subject_model = "subject " + std::to_string(*subject) +
                    " has no stored rig: identity calibrated on the first frames";
  }
  std::vector<float> take_values;
  int take_frames = 0;
  double take_start_s = 0.0;
  // dlib on the colour image: every frame (--landmarks dlib) and/or while the face is searched
  // for (--reacquire dlib: detection gives the tracker a starting pose after loss).
  std::optional<TrackLandmarkSource> detector;
  std::string reacquire_note = "depth only (nearest surface, last pose)";
  if (landmark_source == "dlib" || reacquire == "dlib") {
    auto loaded = load_landmark_detector(options.get("shape-predictor"));
    if (loaded) {
      detector.emplace(std::move(*loaded), info.calibration);
      reacquire_note =
          reacquire == "dlib" ? "dlib detection on the colour image, then depth" : reacquire_note;
    } else if (landmark_source == "dlib") {
      return report_failure(loaded.error());
    } else {
      std::cerr << "track: " << loaded.error().message << "; re-acquiring from depth only\n";
    }
  }
  std::vector<double> landmark_ms;
  long long detections = 0, detection_misses = 0;
  bool face_before = false;

  std::unique_ptr<VmcSender> sender;
  if (!options.get("osc").empty()) {
    auto destination = parse_osc_destination(options.get("osc"));
    if (!destination) return report_failure(destination.error());
    auto opened = VmcSender::open(*destination);
    if (!opened) return report_failure(opened.error());
    sender = std::move(*opened);
  }
  std::optional<LiveLinkCsvWriter> csv;
  if (!options.get("csv").empty()) {
    auto opened = LiveLinkCsvWriter::open(options.get("csv"), info.fps > 0 ? info.fps : 30.0);
    if (!opened) return report_failure(opened.error());
    csv.emplace(std::move(*opened));
  }
  const bool print_sse = options.flag("sse");

  std::mt19937_64 rng(1);
  std::normal_distribution<float> noise(0.0f, static_cast<float>(kLandmarkNoisePx));
  std::vector<Eigen::Vector2f> landmark_points(68);
  RgbdFrame frame;
  TrackReport report;
  ArkitFrame out;
  std::string sse;
  std::vector<double> latency, cost;
  long long read = 0, found = 0, lost_reports = 0, timeouts_in_row = 0;
  std::string last_reason;  // the tracker's loss reason on the previous frame
  std::map<std::string, long long> states;
  std::string stop_reason = "end of stream";
  bool camera_failed = false;
  const long long total = *max_frames > 0 ? *max_frames : info.frame_count;
  Progress progress("track", total > 0 ? total : 0);
  const auto t0 = Clock::now();
  while (*max_frames <= 0 || read < *max_frames) {
    auto status = (*camera)->next_frame(frame, std::chrono::milliseconds(1000));
    if (!status) {
      stop_reason = "camera error: " + status.error().message;
      camera_failed = true;
      break;
    }
    if (*status == FrameStatus::kEndOfStream) break;
    if (*status == FrameStatus::kTimeout) {
      if (++timeouts_in_row >= 5) {
        stop_reason = "the camera stopped delivering frames (5 s without a frame)";
        camera_failed = true;
        break;
      }
      continue;
    }
    timeouts_in_row = 0;
    const auto arrival = Clock::now();
    const TrackLandmarks* landmarks = nullptr;
    TrackLandmarks truth_landmarks;
    if (landmark_source == "truth") {
      if (const FrameTruth* truth = (*camera)->truth()) {
        for (int l = 0; l < 68; ++l) {
          landmark_points[static_cast<std::size_t>(l)] =
              truth->landmarks_depth_px[static_cast<std::size_t>(l)].cast<float>() +
              Eigen::Vector2f(noise(rng), noise(rng));
        }
        truth_landmarks.points = landmark_points;
        landmarks = &truth_landmarks;
      }
    }
    if (detector && (landmark_source == "dlib" || (reacquire == "dlib" && !face_before))) {
      const LandmarkFrameResult found = detector->detect(frame.color, frame.depth_mm);
      landmark_ms.push_back(found.ms);
      if (found.found) {
        ++detections;
        landmarks = detector->landmarks();
      } else {
        ++detection_misses;
      }
    }
    (*tracker)->track(frame.depth_mm, frame.depth_host_time_s, landmarks, report);
    face_before = report.face_found;
    out.index = frame.index;
    out.time_s = frame.depth_host_time_s;
    out.face_found = report.face_found;
    out.camera_from_model = report.camera_from_model;
    mapping->to_arkit(
        std::span<const float>(report.weights.data(), static_cast<std::size_t>(report.shape_count)),
        out.weights);
    if (sender) {
      if (auto sent = sender->send(out); !sent) {
        std::cerr << "facebooth: " << sent.error().message << "\n";
      }
    }
    latency.push_back(ms_between(arrival, Clock::now()));
    cost.push_back(report.times.total_ms());
    if (csv) {
      if (auto r = csv->append(to_livelink_row(out)); !r) return report_failure(r.error());
    }
    if (store) {
      if (take_frames == 0) take_start_s = out.time_s;
      append_take_frame(out, take_start_s, take_values);
      ++take_frames;
    }
    if (print_sse) {
      format_sse_event(out, sse);
      std::cerr << sse;
    }
    ++read;
    if (report.face_found) ++found;
    if (report.state == TrackState::kLost) {
      ++lost_reports;
      std::cerr << "track: frame " << frame.index << ": face lost (" << report.loss_reason << ")\n";
    } else if (report.state == TrackState::kSearching && *report.loss_reason &&
               last_reason != report.loss_reason) {
      // Once per reason: "no face found" every frame of an empty room says nothing new.
      std::cerr << "track: frame " << frame.index << ": searching (" << report.loss_reason << ")\n";
    }
    last_reason = report.loss_reason;
    ++states[to_string(report.state)];
    progress.update(read);
  }
  (*camera)->stop();
  if (csv) {
    if (auto r = csv->close(); !r) return report_failure(r.error());
  }
  const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  nlohmann::json result;
  if (store && take_frames > 0) {
    if (!subject) {
      auto added = store->add_subject("tracking take");
      if (!added) return report_failure(added.error());
      subject = *added;
    }
    TakeInfo take;
    take.subject = *subject;
    take.fps = info.fps > 0 ? info.fps : 30.0;
    take.shape_names = take_columns();
    take.frame_count = take_frames;
    auto id = store->add_take(take, take_values);
    if (!id) return report_failure(id.error());
    result["take"] = *id;
    result["subject"] = *subject;
    result["store"] = store_path;
  } else if (store) {
    result["take"] = nullptr;  // no frame: nothing to store
  }
  result["subject_model"] = subject_model;
  result["camera"] = uri;
  result["frames"] = read;
  result["frames_with_face"] = found;
  result["loss_reports"] = lost_reports;
  result["states"] = states;
  result["calibrated"] = (*tracker)->calibrated();
  result["stopped"] = stop_reason;
  result["fps"] = seconds > 0 ? static_cast<double>(read) / seconds : 0.0;
  result["ms_per_frame"] = stats_of(cost).mean;
  result["latency_ms"] = to_json(stats_of(latency));
  result["landmarks"] =
      landmark_source == "truth"  ? "ground truth + N(0, 1.5 px) (synthetic camera only)"
      : landmark_source == "dlib" ? "dlib HOG + shape_predictor_68 on the colour image"
                                  : "none (depth only)";
  result["reacquire"] = reacquire_note;
  if (detector) {
    result["detections"] = detections;
    result["detection_misses"] = detection_misses;
    result["landmark_ms"] = to_json(stats_of(landmark_ms));
  }
  if (sender) {
    result["osc"] = sender->options().host + ":" + std::to_string(sender->options().port);
    result["osc_datagrams"] = sender->datagrams_sent();
    result["osc_messages"] = sender->messages_sent();
  }
  if (csv) result["csv"] = options.get("csv");
  std::cout << result.dump(2) << std::endl;
  return camera_failed ? kExitFailure : kExitOk;
}

}  // namespace

std::vector<Command> tracking_commands() {
  return {
      {{"eval track",
        "tracking accuracy on synthetic takes with ground truth (weights, pose, occluder)",
        "Prints one JSON object: weight_mae, pose_error_deg, pose_error_mm (with landmarks), the "
        "same depth-only, occluded_unaffected_weight_error, occlusion_recovery_frames, per take "
        "and per shape figures. Landmarks are ground truth + 1.5 px noise.",
        {{"seeds", "N", "synthetic takes (seeds 1..N)", "5"},
         {"frames", "N", "frames per take", "150"},
         {"active", "N", "animated shapes per take", "5"},
         {"neutral-frames", "N",
          "frames each take (and occluder take) holds a neutral face before its expressions "
          "start: the calibration window",
          "20"},
         {"occluder-seed", "N", "seed of the first occluder take", "1000"},
         {"occluder-takes", "N", "occluder takes (seeds occluder-seed ..)", "5"},
         {"occluder-identity", "calibrated|known",
          "the occluder takes' subject: calibrated by the tracker (as on the device), or the "
          "true identity loaded (tells calibration error from the solve's own)",
          "calibrated"},
         {"landmarks", "truth|dlib",
          "landmarks of the with-landmarks runs: ground truth + 1.5 px noise, or dlib on the "
          "synthetic colour render",
          "truth"},
         {"shape-predictor", "PATH", "dlib 68-point model (--landmarks dlib)", kShapePredictor},
         {"set", "K=V,...", "tracker option overrides for tuning (e.g. temporal_frames=1)", ""},
         {"json", "", "print JSON (the only output format; accepted for symmetry)", ""}}},
       run_eval_track},
      {{"bench track",
        "per-frame tracking cost (ICP + weight solve) and frame-to-OSC latency, one core",
        "Prints one JSON object: ms_per_frame (depth only), ms_per_frame_with_landmarks (dlib "
        "detection on the colour image included), latency_ms (frame arrival -> VMC datagrams "
        "sent on loopback) and the stage split.",
        {{"frames", "N", "frames of the synthetic take", "150"},
         {"shape-predictor", "PATH", "dlib 68-point model", kShapePredictor},
         {"set", "K=V,...", "tracker option overrides, as eval track takes them", ""},
         {"json", "", "print JSON (the only output format; accepted for symmetry)", ""}}},
       run_bench_track},
      {{"track",
        "run the tracker live on a camera; stream VMC over OSC and/or record Live Link CSV",
        "Calibrates the identity on the first frames (hold a neutral face), or loads the "
        "subject's stored rig (--rig-from-store), then tracks. Prints a JSON summary at the end "
        "(with --store: the stored take's id); loss of the face is reported on stderr and "
        "tracking resumes when the face is found again.",
        {{"camera", "URI", "camera URI, e.g. synthetic:frames=300 or freenect:0", ""},
         {"osc", "HOST:PORT", "send VMC (OSC/UDP) here; port 39539 if omitted", ""},
         {"csv", "FILE", "record a Live Link Face CSV take", ""},
         {"store", "DIR",
          "record the take in this session store (export it with `facebooth "
          "export --take ID --store DIR --out OUT`)",
          ""},
         {"subject", "ID", "store the take under this subject (default: a new subject)", ""},
         {"rig-from-store", "",
          "track with --subject's newest stored rig (face model topology) instead of "
          "calibrating; falls back to calibration when the subject has no rig",
          ""},
         {"frames", "N", "stop after N frames (0 = until the stream ends)", "0"},
         {"calibration-frames", "N", "frames for the identity fit", "10"},
         {"landmarks", "dlib|truth|none",
          "2D landmarks in the weight solve: dlib on the colour image every frame, ground truth "
          "+ noise (synthetic camera only), or none",
          "none"},
         {"reacquire", "dlib|depth",
          "finding the face at the start and after loss: dlib detection on the colour image "
          "(falls back to depth when the model is missing), or depth only",
          "dlib"},
         {"shape-predictor", "PATH", "dlib 68-point model", kShapePredictor},
         {"sse", "", "also print the kiosk's SSE events to stderr", ""}}},
       run_track},
  };
}

}  // namespace fb::cli
