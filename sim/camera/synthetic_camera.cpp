#include "sim/camera/synthetic_camera.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <numbers>
#include <string>
#include <thread>

#include "algo/core/mix64.hpp"
#include "drivers/camera/common/camera_uri.hpp"
#include "sim/camera/board_scene.hpp"
#include "sim/camera/color_fill.hpp"
#include "sim/camera/expressive_track.hpp"
#include "sim/camera/render_ahead.hpp"
#include "sim/camera/world_presets.hpp"
#include "storage/asset_files.hpp"

namespace fb {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;
// 60 MHz device clock at 30 fps.
constexpr std::uint32_t kTicksPerFrame = 2'000'000;

double hashed_uniform(std::uint64_t seed, std::uint64_t stream, std::uint64_t k) {
  const auto bits = mix64(mix64(seed ^ (stream << 56)) + k);
  return (static_cast<double>(bits >> 11) + 0.5) * 0x1.0p-53;  // (0, 1)
}

// Box-Muller from two counter-based uniforms.
double hashed_gaussian(std::uint64_t seed, std::uint64_t stream, std::uint64_t k) {
  const double u1 = hashed_uniform(seed, stream, 2 * k),
               u2 = hashed_uniform(seed, stream, 2 * k + 1);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
}

constexpr std::uint64_t kStreamIdentity = 1, kStreamSkin = 2;

enum class CapKind { kEye, kMouth, kFlat };

struct Cap {
  std::vector<std::uint32_t> loop;  // boundary vertices in order (edges loop[i] -> loop[i+1])
  CapKind kind = CapKind::kFlat;
};

// Boundary loops of a triangle mesh: directed edges whose reverse is absent, chained.
std::vector<std::vector<std::uint32_t>> boundary_loops(std::span<const std::uint32_t> triangles) {
  std::map<std::pair<std::uint32_t, std::uint32_t>, int> edges;
  for (std::size_t t = 0; t + 2 < triangles.size(); t += 3) {
    for (int e = 0; e < 3; ++e) edges[{triangles[t + e], triangles[t + (e + 1) % 3]}]++;
  }
  std::map<std::uint32_t, std::uint32_t> next;
  for (const auto& [edge, count] : edges) {
    if (!edges.count({edge.second, edge.first})) next[edge.first] = edge.second;
  }
  std::vector<std::vector<std::uint32_t>> loops;
  std::map<std::uint32_t, bool> used;
  for (const auto& [start, unused] : next) {
    if (used[start]) continue;
    std::vector<std::uint32_t> loop{start};
    used[start] = true;
    auto it = next.find(start);
    bool closed = false;
    while (it != next.end() && loop.size() <= next.size()) {
      if (it->second == start) {
        closed = true;
        break;
      }
      if (used[it->second]) break;
      loop.push_back(it->second);
      used[it->second] = true;
      it = next.find(it->second);
    }
    if (closed && loop.size() >= 3) loops.push_back(std::move(loop));
  }
  return loops;
}

bool inside_polygon(const Eigen::Vector2f& p, std::span<const Eigen::Vector2f> poly) {
  bool inside = false;
  for (std::size_t i = 0, j = poly.size() - 1; i < poly.size(); j = i++) {
    if ((poly[i].y() > p.y()) != (poly[j].y() > p.y()) &&
        p.x() < (poly[j].x() - poly[i].x()) * (p.y() - poly[i].y()) / (poly[j].y() - poly[i].y()) +
                    poly[i].x()) {
      inside = !inside;
    }
  }
  return inside;
}

float segment_distance(const Eigen::Vector2f& p, const Eigen::Vector2f& a,
                       const Eigen::Vector2f& b) {
  const Eigen::Vector2f ab = b - a;
  const float s = std::clamp((p - a).dot(ab) / std::max(ab.squaredNorm(), 1e-12f), 0.0f, 1.0f);
  return (a + s * ab - p).norm();
}

float polyline_distance(const Eigen::Vector2f& p, std::span<const Eigen::Vector2f> line,
                        bool closed) {
  float best = std::numeric_limits<float>::infinity();
  for (std::size_t i = 0; i + 1 < line.size(); ++i) {
    best = std::min(best, segment_distance(p, line[i], line[i + 1]));
  }
  if (closed) best = std::min(best, segment_distance(p, line.back(), line.front()));
  return best;
}

Eigen::Vector3f rgb(int r, int g, int b) {
  return Eigen::Vector3f(r, g, b) / 255.0f;
}

// Albedo palette (linear 0..1).
const Eigen::Vector3f kSkin = rgb(205, 156, 130);
const Eigen::Vector3f kBrow = rgb(72, 52, 42);
const Eigen::Vector3f kEye = rgb(38, 30, 30);
const Eigen::Vector3f kLip = rgb(168, 74, 76);
const Eigen::Vector3f kMouthInside = rgb(70, 22, 26);

Result<double> parse_number(const std::string& key, const std::string& text, double lo, double hi) {
  double value = 0.0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || end != text.data() + text.size() || !(value >= lo && value <= hi)) {
    return fail("synthetic: bad value '" + text + "' for " + key + "; expected a number in [" +
                std::to_string(lo) + ", " + std::to_string(hi) + "]");
  }
  return value;
}

constexpr std::string_view kAccepted =
    "accepted: seed=N, expr=neutral|NAME[:WEIGHT]+NAME... (model shapes or guide expressions), "
    "motion=headturn|static, anim=expressive (a scripted jaw, smile, blink and brow take), "
    "frames=N, realtime=0|1 (deliver on the sensor's 30 fps clock, rendered ahead), "
    "stall_after=N, fail_after=N (fault injection: stop delivering, or fail, after N frames), "
    "distance=MM, noise=on|off, background=MM|off, identity=random|neutral, "
    "unit=SEED (a decalibrated Kinect unit), reg_dx=PX, reg_dy=PX, reg_rot=DEG, depth_scale=S, "
    "calibrated=0|1 (report the unit's true calibration instead of the defaults), "
    "world=realistic|identity|texture|hair|clutter|noise|unit|none, world_seed=N, displace=MM, "
    "asym=MM, id_scale=S, id_extreme=N, texture=on|off, tone=0..1, light=fixed|vary, "
    "hair=on|off, beard=on|off, torso=on|off, desk=on|off, hand=on|off, hand_pass=on|off|START, "
    "offset_x=PX, offset_y=PX, block_noise=RAW, block_px=N, speckle=RATE; or "
    "target=checkerboard with its own keys (board=COLSxROWS:SIZEmm, ...)";

}  // namespace

RegistrationCorrection random_unit_correction(std::uint64_t seed) {
  RegistrationCorrection c;
  if (seed == 0) return c;
  // Counter-based draws so a unit is the same on every build and platform.
  auto uniform = [&](std::uint64_t k) {
    const std::uint64_t h = mix64(mix64(seed * 0x9E3779B97F4A7C15ull + 0x5157u) + k);
    return static_cast<double>(h >> 11) * (2.0 / 9007199254740992.0) - 1.0;  // [-1, 1)
  };
  c.dx_px = 20.0 * uniform(1);
  c.dy_px = 20.0 * uniform(2);
  c.rotation_deg = 1.0 * uniform(3);
  c.depth_scale = 1.0 + 0.05 * uniform(4);
  c.inverse_depth_offset_per_m = 0.02 * uniform(5);
  return c;
}

Result<std::vector<float>> parse_expression_spec(std::string_view spec, const FaceModel& model,
                                                 const GuideSet* guide) {
  std::vector<float> weights(static_cast<std::size_t>(model.expression_count), 0.0f);
  if (spec.empty() || spec == "neutral") return weights;
  std::size_t start = 0;
  while (start <= spec.size()) {
    const auto plus = spec.find('+', start);
    const auto term = spec.substr(start, plus == std::string_view::npos ? spec.npos : plus - start);
    const auto colon = term.find(':');
    const std::string name(term.substr(0, colon));
    float weight = 1.0f;
    if (colon != std::string_view::npos) {
      const auto text = term.substr(colon + 1);
      const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), weight);
      if (ec != std::errc() || end != text.data() + text.size() ||
          !(weight >= -1.0f && weight <= 2.0f)) {
        return fail("synthetic: bad expression weight '" + std::string(text) + "' for '" + name +
                    "'; expected a number in [-1, 2], e.g. expr=jawOpen:0.6+mouthSmile_L");
      }
    }
    const int index = model.expression_index(name);
    const int recipe = guide != nullptr ? guide->find(name) : -1;
    if (index >= 0) {
      weights[static_cast<std::size_t>(index)] += weight;
    } else if (recipe >= 0) {
      auto recipe_weights =
          guide_weights(guide->expressions[static_cast<std::size_t>(recipe)], model);
      if (!recipe_weights) return fail("synthetic: " + recipe_weights.error().message);
      for (std::size_t j = 0; j < weights.size() && j < recipe_weights->size(); ++j) {
        weights[j] += weight * (*recipe_weights)[j];
      }
    } else {
      std::string names;
      if (guide != nullptr) {
        for (const auto& g : guide->expressions) names += (names.empty() ? "" : ", ") + g.name;
        names = "guide expressions: " + names + "; shapes: ";
      }
      std::string shapes;
      for (const auto& n : model.expression_names) shapes += (shapes.empty() ? "" : ", ") + n;
      return fail("synthetic: unknown expression '" + name + "' in expr=" + std::string(spec) +
                  "; use 'neutral' or NAME[:WEIGHT] terms joined by '+', " + names + shapes);
    }
    if (plus == std::string_view::npos) break;
    start = plus + 1;
  }
  return weights;
}

namespace {

// The stream's keys: its length, real-time delivery and injected faults.
bool is_stream_key(const std::string& key) {
  return key == "frames" || key == "realtime" || key == "stall_after" || key == "fail_after";
}

Result<void> parse_stream_key(const std::string& key, const std::string& value,
                              SyntheticOptions& options) {
  if (key == "realtime") {
    if (value != "0" && value != "1")
      return fail("synthetic: bad realtime '" + value + "'; expected 0 or 1");
    options.realtime = value == "1";
    return success();
  }
  auto n = parse_number(key, value, key == "frames" ? 1 : 0, key == "frames" ? 1e6 : 1e9);
  if (!n) return n.failure();
  if (*n != std::floor(*n))
    return fail("synthetic: " + key + " must be an integer, got '" + value + "'");
  if (key == "frames") options.frame_count = static_cast<int>(*n);
  if (key == "stall_after") options.stall_after = static_cast<long long>(*n);
  if (key == "fail_after") options.fail_after = static_cast<long long>(*n);
  return success();
}

}  // namespace

// Controls override the URI's keys of the same meaning (camera_controls.hpp).
Result<void> apply_controls(const CameraControls& controls,
                            std::map<std::string, std::string>& values) {
  for (const auto& control : controls) {
    if (control.name == kControlExpression) {
      values["expr"] = control.value;
    } else if (control.name == kControlMotion || control.name == kControlFrames ||
               control.name == kControlRealtime) {
      values[control.name] = control.value;
    } else {
      return fail("synthetic: unknown control '" + control.name + "'; expected " +
                  std::string(kSyntheticControls));
    }
  }
  return success();
}

Result<SyntheticOptions> parse_synthetic_options(std::string_view arguments, const FaceModel& model,
                                                 const CameraControls& controls) {
  auto values = parse_key_values(arguments);
  if (!values) {
    return fail("synthetic: " + values.error().message + "; " + std::string(kAccepted));
  }
  if (auto ok = apply_controls(controls, *values); !ok) return ok.failure();
  SyntheticOptions options;
  bool random_identity = true;
  bool expressive = false;
  bool decalibrated = false;
  int calibrated = -1;
  RegistrationCorrection& unit = options.calibration.correction;
  for (const auto& [key, value] : *values) {
    if (key == "unit") {
      auto n = parse_number(key, value, 0, 1e15);
      if (!n) return n.failure();
      if (*n != std::floor(*n))
        return fail("synthetic: unit must be a non-negative integer seed, got '" + value + "'");
      const RegistrationCorrection drawn = random_unit_correction(static_cast<std::uint64_t>(*n));
      unit = drawn;
      decalibrated = true;
    } else if (key == "reg_dx" || key == "reg_dy") {
      auto px = parse_number(key, value, -40, 40);
      if (!px) return px.failure();
      (key == "reg_dx" ? unit.dx_px : unit.dy_px) = *px;
      decalibrated = true;
    } else if (key == "reg_rot") {
      auto deg = parse_number(key, value, -5, 5);
      if (!deg) return deg.failure();
      unit.rotation_deg = *deg;
      decalibrated = true;
    } else if (key == "depth_scale") {
      auto scale = parse_number(key, value, 0.8, 1.2);
      if (!scale) return scale.failure();
      unit.depth_scale = *scale;
      decalibrated = true;
    } else if (is_stream_key(key)) {
      if (auto ok = parse_stream_key(key, value, options); !ok) return ok.failure();
    } else if (key == "calibrated") {
      if (value != "0" && value != "1")
        return fail("synthetic: bad calibrated '" + value + "'; expected 0 or 1");
      calibrated = value == "1" ? 1 : 0;
    } else if (key == "seed") {
      std::uint64_t seed = 0;
      const auto [end, ec] = std::from_chars(value.data(), value.data() + value.size(), seed);
      if (ec != std::errc() || end != value.data() + value.size()) {
        return fail("synthetic: bad seed '" + value + "'; expected a non-negative integer");
      }
      options.seed = seed;
    } else if (key == "expr") {
      // Guide recipe names (expr=smile) need the guide file; shape names alone do not.
      auto guide = load_guide_expressions(model);
      auto weights = parse_expression_spec(value, model, guide ? &*guide : nullptr);
      if (!weights) return weights.failure();
      options.expression_weights = std::move(*weights);
    } else if (key == "motion") {
      if (value == "headturn") {
        options.motion = SyntheticMotion::kHeadTurn;
      } else if (value == "static") {
        options.motion = SyntheticMotion::kStatic;
      } else {
        return fail("synthetic: bad motion '" + value + "'; expected headturn or static");
      }
    } else if (key == "anim") {
      if (value != "expressive" && value != "none") {
        return fail("synthetic: bad anim '" + value + "'; expected expressive or none");
      }
      expressive = value == "expressive";
    } else if (key == "distance") {
      auto mm = parse_number(key, value, 500, 4000);
      if (!mm) return mm.failure();
      options.distance_mm = *mm;
    } else if (key == "noise") {
      if (value != "on" && value != "off") {
        return fail("synthetic: bad noise '" + value + "'; expected on or off");
      }
      options.sensor.depth_noise = value == "on";
    } else if (key == "background") {
      if (value == "off") {
        options.background_mm = 0.0;
      } else {
        auto mm = parse_number(key, value, 600, 8000);
        if (!mm) return fail(mm.error().message + " or off");
        options.background_mm = *mm;
      }
    } else if (key == "identity") {
      if (value != "random" && value != "neutral") {
        return fail("synthetic: bad identity '" + value + "'; expected random or neutral");
      }
      random_identity = value == "random";
    } else if (is_world_key(key)) {
      // Applied after the loop: a preset first, explicit keys over it (world_presets.hpp).
    } else {
      return fail("synthetic: unknown option '" + key + "'; " + std::string(kAccepted));
    }
  }
  if (!random_identity) options.identity_coeffs = std::vector<float>();
  if (expressive) options.expression_track = expressive_track(model, options.frame_count);
  if (auto ok = apply_world_keys(*values, options); !ok) return ok.failure();
  // A decalibrated unit reports the defaults unless calibrated=1; calibrated=0 alone reports
  // the defaults for a unit that has none to differ by (harmless).
  if ((decalibrated && calibrated != 1) || calibrated == 0) {
    KinectCalibration reported = options.calibration;
    reported.correction = RegistrationCorrection{};
    options.reported_calibration = reported;
  }
  if (options.background_mm > 0.0 && options.background_mm <= options.distance_mm + 150.0) {
    return fail("synthetic: background=" + std::to_string(options.background_mm) +
                " mm must be at least 150 mm behind distance=" +
                std::to_string(options.distance_mm) + " mm (or background=off)");
  }
  return options;
}

struct SyntheticCamera::State {
  State(const KinectRegistration& registration, const SyntheticOptions& o)
      : options(o), sensor(registration, o.sensor) {}

  CameraInfo info;
  SyntheticOptions options;
  KinectSensorModel sensor;
  // A decalibrated unit's depth in millimetres as its driver reports it: the raw disparity
  // through the reported (default) disparity law, not the unit's true one.
  std::optional<KinectRegistration> reported_registration;

  int skin_vertex_count = 0;
  int mesh_vertex_count = 0;            // skin + cap apexes
  std::vector<float> identity_mesh;     // 3 * skin_vertex_count, identity applied
  std::vector<float> expression_basis;  // copied only for expression tracks
  int expression_count = 0;
  std::vector<float> current_weights;
  std::vector<float> evaluated;  // 3 * skin_vertex_count scratch
  std::vector<Cap> caps;
  std::vector<std::uint32_t> triangles;   // skin, caps, wall
  std::uint32_t mesh_triangle_count = 0;  // skin + caps (ids below this are the head)
  std::array<std::uint32_t, 68> landmarks{};
  Eigen::Vector3d rest_centroid = Eigen::Vector3d::Zero();

  std::vector<Eigen::Vector3f> model_vertices;  // mesh_vertex_count, current expression
  std::vector<Eigen::Vector3f> model_normals;
  std::vector<Eigen::Vector3f> albedo;
  std::vector<Eigen::Vector3f> scene_vertices;  // camera frame, + wall corners

  // The realistic world (synthetic_world.hpp): props, hair/beard regions, texture inputs.
  std::optional<WorldProps> props;
  WorldRegions regions;
  std::vector<float> brow_weight;       // per mesh vertex, for the brow texture
  std::vector<MaterialPixel> material;  // per depth pixel, hair/beard weights
  Eigen::Vector3f skin = Eigen::Vector3f::Zero();

  SensorFrame sensor_frame;
  FrameTruth truth;                   // of the frame last delivered
  std::vector<float> identity_truth;  // the subject's identity coefficients (sigma units)
  Image<float> color_z;
  Image<std::uint8_t> color_mark;
  ColorImage color;

  bool started = false;
  std::uint64_t next_index = 0;
  // realtime=1: renders ahead on its own thread (declared last: stopped before the rest goes).
  std::unique_ptr<RenderAhead> ahead;

  // Renders frame `index` from the current options into `frame` and `truth`.
  Result<void> render(std::uint64_t index, RgbdFrame& frame, FrameTruth& truth,
                      bool with_noiseless_depth, bool with_depth_mm);
  void depth_from_raw(RgbdFrame& frame) const;
  void finish_realtime();
  void set_expression(std::span<const float> basis, std::span<const float> weights);
  RigidPose pose_at(std::uint64_t index) const;
  void shade_color(std::uint64_t frame_index, const RigidPose& camera_from_model);
  void world_depth(std::uint64_t noise_seed);
  Eigen::Vector3f head_albedo(std::int32_t t, float b1, float b2) const;
  Eigen::Vector2d color_position(const Eigen::Vector2d& px, double z) const;
};

void SyntheticCamera::State::set_expression(std::span<const float> basis,
                                            std::span<const float> weights) {
  const std::size_t n = identity_mesh.size();
  std::copy(identity_mesh.begin(), identity_mesh.end(), evaluated.begin());
  const std::size_t count = std::min<std::size_t>(weights.size(), expression_count);
  for (std::size_t j = 0; j < count; ++j) {
    const float w = weights[j];
    if (w == 0.0f) continue;
    const float* shape = basis.data() + j * n;
    for (std::size_t i = 0; i < n; ++i) evaluated[i] += w * shape[i];
  }
  for (int v = 0; v < skin_vertex_count; ++v) {
    model_vertices[v] =
        Eigen::Vector3f(evaluated[3 * v], evaluated[3 * v + 1], evaluated[3 * v + 2]);
  }
  // Cap apexes: loop centroid; the mouth's sits 15 mm into the head so an open mouth shows a
  // cavity rather than a flat membrane.
  for (std::size_t c = 0; c < caps.size(); ++c) {
    Eigen::Vector3f centroid = Eigen::Vector3f::Zero();
    for (auto v : caps[c].loop) centroid += model_vertices[v];
    centroid /= static_cast<float>(caps[c].loop.size());
    if (caps[c].kind == CapKind::kMouth) centroid.z() -= 15.0f;
    model_vertices[skin_vertex_count + c] = centroid;
  }
  // Area-weighted vertex normals (unnormalised cross products summed).
  std::fill(model_normals.begin(), model_normals.end(), Eigen::Vector3f::Zero());
  for (std::uint32_t t = 0; t < mesh_triangle_count; ++t) {
    const auto a = triangles[3 * t], b = triangles[3 * t + 1], c = triangles[3 * t + 2];
    const Eigen::Vector3f n =
        (model_vertices[b] - model_vertices[a]).cross(model_vertices[c] - model_vertices[a]);
    model_normals[a] += n;
    model_normals[b] += n;
    model_normals[c] += n;
  }
  for (auto& n : model_normals) n.normalize();
}

RigidPose SyntheticCamera::State::pose_at(std::uint64_t index) const {
  // The world's offset moves the face centre across the image (explicit tracks too).
  auto placed = [&](RigidPose pose) {
    const double z = pose.apply(rest_centroid).z();
    const auto& k = sensor.intrinsics();
    pose.translation += Eigen::Vector3d(options.world.offset_x_px * z / k.fx,
                                        options.world.offset_y_px * z / k.fy, 0.0);
    return pose;
  };
  if (!options.camera_from_model_track.empty()) {
    return placed(options.camera_from_model_track[std::min<std::size_t>(
        index, options.camera_from_model_track.size() - 1)]);
  }
  double yaw = 0.0, pitch = 0.0;
  if (options.motion == SyntheticMotion::kHeadTurn) {
    const double t = static_cast<double>(index) / kKinectFps;
    const double phase = 2.0 * std::numbers::pi * t / options.motion_period_s;
    yaw = options.yaw_amplitude_deg * std::sin(phase);
    pitch = options.pitch_amplitude_deg * std::sin(2.0 * phase);
  }
  const Eigen::Quaterniond flip(Eigen::AngleAxisd(std::numbers::pi, Eigen::Vector3d::UnitX()));
  const Eigen::Quaterniond head = Eigen::AngleAxisd(yaw * kDeg, Eigen::Vector3d::UnitY()) *
                                  Eigen::AngleAxisd(pitch * kDeg, Eigen::Vector3d::UnitX());
  RigidPose pose;
  pose.rotation = (flip * head).normalized();
  pose.translation = Eigen::Vector3d(0.0, 0.0, options.distance_mm) - flip * rest_centroid;
  return placed(pose);
}

Eigen::Vector2d SyntheticCamera::State::color_position(const Eigen::Vector2d& px, double z) const {
  Eigen::Vector2d out;
  if (!sensor.registration().depth_to_color_interpolated(px.x(), px.y(), std::round(z), out.x(),
                                                         out.y()))
    return Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN());
  return out;
}

Eigen::Vector3f SyntheticCamera::State::head_albedo(std::int32_t t, float b1, float b2) const {
  const auto a = triangles[3 * t], b = triangles[3 * t + 1], c = triangles[3 * t + 2];
  const float b0 = 1.0f - b1 - b2;
  const Eigen::Vector3f plain = b0 * albedo[a] + b1 * albedo[b] + b2 * albedo[c];
  if (!options.world.texture) return plain;
  // The texture sticks to the skin: sampled at the rest-pose point (caps at their current one).
  const auto skin_count = static_cast<std::uint32_t>(skin_vertex_count);
  auto rest = [&](std::uint32_t v) {
    return v < skin_count ? Eigen::Vector3f(identity_mesh[3 * v], identity_mesh[3 * v + 1],
                                            identity_mesh[3 * v + 2])
                          : model_vertices[v];
  };
  auto weight = [&](const std::vector<float>& w, std::uint32_t v) {
    return v < w.size() ? w[v] : 0.0f;
  };
  auto mix = [&](const std::vector<float>& w) {
    return b0 * weight(w, a) + b1 * weight(w, b) + b2 * weight(w, c);
  };
  return textured_albedo(options.world, plain, b0 * rest(a) + b1 * rest(b) + b2 * rest(c),
                         mix(regions.hair), mix(regions.beard), mix(brow_weight));
}

void SyntheticCamera::State::world_depth(std::uint64_t noise_seed) {
  if (!options.world.hair && !options.world.beard) return;
  const auto& raster = sensor.camera_raster();
  material.assign(raster.triangle.size(), MaterialPixel{});
  const auto skin_count = static_cast<std::uint32_t>(skin_vertex_count);
  for (std::size_t i = 0; i < raster.triangle.size(); ++i) {
    const std::int32_t t = raster.triangle[i];
    if (t == kNoTriangle || static_cast<std::uint32_t>(t) >= mesh_triangle_count) continue;
    const float b1 = raster.bary1[i], b2 = raster.bary2[i], b0 = 1.0f - b1 - b2;
    const std::uint32_t v[3] = {triangles[3 * t], triangles[3 * t + 1], triangles[3 * t + 2]};
    const float w[3] = {b0, b1, b2};
    for (int k = 0; k < 3; ++k) {
      if (v[k] >= skin_count) continue;
      material[i].hair += w[k] * regions.hair[v[k]];
      material[i].beard += w[k] * regions.beard[v[k]];
    }
  }
  degrade_material_depth(sensor, material, mix64(noise_seed ^ 0x4a1b), sensor_frame);
}

void SyntheticCamera::State::shade_color(std::uint64_t frame_index,
                                         const RigidPose& camera_from_model) {
  const auto& raster = sensor.camera_raster();
  const auto& registration = sensor.registration();
  const int w = raster.width, h = raster.height;
  color.resize(w, h);
  color_z.resize(w, h);
  color_mark.resize(w, h);
  std::fill(color_z.pixels.begin(), color_z.pixels.end(), std::numeric_limits<float>::infinity());
  std::fill(color_mark.pixels.begin(), color_mark.pixels.end(), std::uint8_t{0});

  // Key light from the upper left of the camera, expressed in the model frame so the stored
  // model normals can be used directly: l_model = R^T l_camera.
  const WorldLight world_light_now = world_light(options.world, frame_index);
  const Eigen::Vector3f light_camera = world_light_now.to_light;
  const Eigen::Vector3f light =
      (camera_from_model.rotation.conjugate().cast<float>() * light_camera).normalized();
  const float kAmbient = world_light_now.ambient, kDiffuse = world_light_now.diffuse;
  const Rgb8 wall = options.wall_color;

  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const std::size_t i = raster.index(x, y);
      const std::int32_t t = raster.triangle[i];
      if (t == kNoTriangle) continue;
      const float z = raster.depth[i];
      double cx = 0.0, cy = 0.0;
      // Rounded like std::lround (z > 0), without the libm call per pixel.
      const auto mm = static_cast<std::uint16_t>(std::min(static_cast<double>(z) + 0.5, 65535.0));
      if (!registration.depth_to_color(x, y, mm, cx, cy)) continue;
      const int px = static_cast<int>(cx + 0.5), py = static_cast<int>(cy + 0.5);  // cx, cy >= 0
      if (px < 0 || py < 0 || px >= w || py >= h) continue;
      const std::size_t j = static_cast<std::size_t>(py) * w + px;
      if (!(z < color_z.pixels[j])) continue;
      color_z.pixels[j] = z;
      color_mark.pixels[j] = 1;
      Eigen::Vector3f value;
      if (props && static_cast<std::uint32_t>(t) >= props->first_triangle()) {
        // A prop: flat-shaded with its triangle's normal (camera frame).
        const auto& p0 = scene_vertices[triangles[3 * t]];
        const Eigen::Vector3f n = (scene_vertices[triangles[3 * t + 1]] - p0)
                                      .cross(scene_vertices[triangles[3 * t + 2]] - p0)
                                      .normalized();
        const float intensity = kAmbient + kDiffuse * std::max(0.0f, n.dot(light_camera));
        value = props->albedo(static_cast<std::uint32_t>(t)) * intensity * 255.0f;
      } else if (static_cast<std::uint32_t>(t) >= mesh_triangle_count) {
        color.pixels[j] = wall;
        continue;
      } else {
        const auto a = triangles[3 * t], b = triangles[3 * t + 1], c = triangles[3 * t + 2];
        const float b1 = raster.bary1[i], b2 = raster.bary2[i], b0 = 1.0f - b1 - b2;
        const Eigen::Vector3f n =
            (b0 * model_normals[a] + b1 * model_normals[b] + b2 * model_normals[c]).normalized();
        const Eigen::Vector3f albedo_here = head_albedo(t, b1, b2);
        const float intensity = kAmbient + kDiffuse * std::max(0.0f, n.dot(light));
        value = albedo_here * intensity * 255.0f;
      }
      value = value.cwiseProduct(world_light_now.tint).cwiseMin(255.0f).cwiseMax(0.0f);
      color.pixels[j] = Rgb8{static_cast<std::uint8_t>(value.x() + 0.5f),
                             static_cast<std::uint8_t>(value.y() + 0.5f),
                             static_cast<std::uint8_t>(value.z() + 0.5f)};
    }
  }

  fill_color_holes(color, color_z, color_mark);
  for (std::size_t j = 0; j < color.pixels.size(); ++j) {
    if (color_mark.pixels[j] == 0) color.pixels[j] = wall;
  }
  if (options.world.texture) {
    // The colour sensor's own noise (about 3 levels per channel), so dlib sees no clean edges.
    const std::uint64_t seed = mix64(mix64(options.seed ^ 0xc0104) + frame_index);
    for (std::size_t j = 0; j < color.pixels.size(); ++j) {
      std::uint8_t* channel[3] = {&color.pixels[j].r, &color.pixels[j].g, &color.pixels[j].b};
      for (int k = 0; k < 3; ++k) {
        const double g = hashed_gaussian(seed, 3, 3 * j + static_cast<std::size_t>(k));
        *channel[k] =
            static_cast<std::uint8_t>(std::clamp(*channel[k] + 3.0 * g + 0.5, 0.0, 255.0));
      }
    }
  }
}

// Ends a real-time take: joins the render thread and logs one line of what it did (the lab's
// benches read it: frames late, memory held).
void SyntheticCamera::State::finish_realtime() {
  if (!ahead) return;
  const auto stats = ahead->stats();
  const long long held = std::min<long long>(stats.slots, stats.rendered);
  const double mb = static_cast<double>(held) * info.width * info.height *
                    (sizeof(std::uint16_t) + sizeof(Rgb8)) / (1024.0 * 1024.0);
  // One line per take: what a bench needs to tell the renderer's share from the reader's.
  std::fprintf(stderr,
               "synthetic camera: real-time take: %lld frames rendered (%.1f ms each), %lld "
               "slots held (%.1f MB), %lld delivered, %lld overwritten, %lld late%s\n",
               stats.rendered, stats.render_ms_mean, held, mb, stats.delivered, stats.overwritten,
               stats.late,
               stats.late > 0 ? " (rendered after their sensor time: this machine is too "
                                "slow for real time)"
                              : "");
  ahead.reset();
}

SyntheticCamera::SyntheticCamera(std::unique_ptr<State> state) : state_(std::move(state)) {}
SyntheticCamera::~SyntheticCamera() {
  if (state_) state_->finish_realtime();
}

const CameraInfo& SyntheticCamera::info() const {
  return state_->info;
}
const FrameTruth* SyntheticCamera::truth() const {
  return state_->next_index > 0 ? &state_->truth : nullptr;
}
const SyntheticOptions& SyntheticCamera::options() const {
  return state_->options;
}
const SensorFrame& SyntheticCamera::sensor_frame() const {
  return state_->sensor_frame;
}
std::span<const MaterialPixel> SyntheticCamera::material_pixels() const {
  return state_->material;
}
Eigen::Vector3f SyntheticCamera::surface_albedo(int t, float b1, float b2) const {
  return state_->head_albedo(t, b1, b2);
}

std::span<const Eigen::Vector3f> SyntheticCamera::model_vertices() const {
  return state_->model_vertices;
}
std::span<const std::uint32_t> SyntheticCamera::model_triangles() const {
  return std::span<const std::uint32_t>(state_->triangles).first(3 * state_->mesh_triangle_count);
}

Result<void> SyntheticCamera::start() {
  State& s = *state_;
  s.finish_realtime();
  s.started = true;
  s.next_index = 0;
  if (s.options.realtime) {
    // The render thread owns the render state from here until stop(); the consumer reads only
    // the slots (render_ahead.hpp). Slots hold raw disparity and colour (depth in mm is made at
    // delivery) and truth without the noiseless depth: 1.5 MB a frame held.
    RenderAheadOptions ahead;
    ahead.frame_count = s.options.frame_count;
    ahead.max_slots = 24;  // 36 MB at most
    ahead.fps = kKinectFps;
    auto started = RenderAhead::start(ahead, [&s](std::uint64_t i, RgbdFrame& f, FrameTruth& t) {
      return s.render(i, f, t, false, false);
    });
    if (!started) return started.failure();
    s.ahead = std::move(*started);
  }
  return success();
}

void SyntheticCamera::stop() {
  State& s = *state_;
  s.finish_realtime();
  s.started = false;
}

std::optional<RenderAhead::Stats> SyntheticCamera::realtime_stats() const {
  if (!state_->ahead) return std::nullopt;
  return state_->ahead->stats();
}

Result<void> SyntheticCamera::State::render(std::uint64_t index, RgbdFrame& frame,
                                            FrameTruth& truth, bool with_noiseless_depth,
                                            bool with_depth_mm) {
  State& s = *this;

  if (!s.options.expression_track.empty()) {
    const auto& weights =
        s.options
            .expression_track[std::min<std::size_t>(index, s.options.expression_track.size() - 1)];
    s.set_expression(s.expression_basis, weights);
    std::fill(s.current_weights.begin(), s.current_weights.end(), 0.0f);
    std::copy_n(weights.begin(), std::min(weights.size(), s.current_weights.size()),
                s.current_weights.begin());
  }

  const RigidPose pose = s.pose_at(index);
  const Eigen::Matrix3f rotation = pose.rotation.toRotationMatrix().cast<float>();
  const Eigen::Vector3f translation = pose.translation.cast<float>();
  for (int v = 0; v < s.mesh_vertex_count; ++v) {
    s.scene_vertices[v] = rotation * s.model_vertices[v] + translation;
  }
  // The wall corners stay where they are (fixed in the camera frame); a passing hand moves.
  if (s.props) s.props->pose(index, pose.apply(s.rest_centroid).cast<float>(), s.scene_vertices);

  const std::uint64_t noise_seed = mix64(mix64(s.options.seed) + index);
  std::span<const std::uint32_t> triangles = s.triangles;
  if (auto captured = s.sensor.capture(s.scene_vertices, triangles, noise_seed, s.sensor_frame);
      !captured) {
    return captured.failure();
  }
  s.world_depth(noise_seed);

  // Ground truth.
  if (truth.identity_coeffs.size() != identity_truth.size()) truth.identity_coeffs = identity_truth;
  truth.camera_from_model = pose;
  truth.expression_weights = s.current_weights;
  const auto& k = s.sensor.intrinsics();
  truth.landmarks_3d.resize(68);
  truth.landmarks_depth_px.resize(68);
  truth.landmarks_color_px.resize(68);
  for (int l = 0; l < 68; ++l) {
    const Eigen::Vector3d p = pose.apply(s.model_vertices[s.landmarks[l]].cast<double>());
    truth.landmarks_3d[l] = p;
    truth.landmarks_depth_px[l] = k.project(p);
    truth.landmarks_color_px[l] = s.color_position(truth.landmarks_depth_px[l], p.z());
  }
  if (with_noiseless_depth) {
    truth.noiseless_depth_mm.resize(k.width, k.height);
    std::copy(s.sensor_frame.noiseless_depth_mm.pixels.begin(),
              s.sensor_frame.noiseless_depth_mm.pixels.end(),
              truth.noiseless_depth_mm.pixels.begin());
  }

  truth.face_hidden_fraction =
      s.props ? face_hidden_fraction(s.sensor.camera_raster(), *s.props, truth.landmarks_depth_px)
              : 0.0;
  s.shade_color(index, pose);

  frame.index = index;
  frame.depth_host_time_s = static_cast<double>(index) / kKinectFps;
  frame.color_host_time_s = frame.depth_host_time_s;
  frame.depth_device_timestamp = static_cast<std::uint32_t>(index * kTicksPerFrame);
  frame.color_device_timestamp = frame.depth_device_timestamp;
  frame.raw_disparity.resize(k.width, k.height);
  frame.color.resize(k.width, k.height);
  std::copy(s.sensor_frame.raw.pixels.begin(), s.sensor_frame.raw.pixels.end(),
            frame.raw_disparity.pixels.begin());
  std::copy(s.color.pixels.begin(), s.color.pixels.end(), frame.color.pixels.begin());
  if (with_depth_mm) s.depth_from_raw(frame);
  return success();
}

// Depth in millimetres as the unit's driver reports it: the raw disparity through the reported
// disparity law (a decalibrated unit's defaults) or the unit's own (every depth is raw_to_mm of
// its raw, kinect_sensor.hpp). Read-only on the render state, so the reader may call it while
// the render thread works.
void SyntheticCamera::State::depth_from_raw(RgbdFrame& frame) const {
  const KinectRegistration& law =
      reported_registration ? *reported_registration : sensor.registration();
  frame.depth_mm.resize(frame.raw_disparity.width, frame.raw_disparity.height);
  law.disparity_to_mm(frame.raw_disparity, frame.depth_mm);
}

Result<FrameStatus> SyntheticCamera::next_frame(RgbdFrame& frame,
                                                std::chrono::milliseconds timeout) {
  State& s = *state_;
  if (!s.started) return fail("synthetic: next_frame() called before start()");
  const auto delivered = static_cast<long long>(s.next_index);
  if (s.options.fail_after >= 0 && delivered >= s.options.fail_after)
    return fail("synthetic: the camera failed after " + std::to_string(delivered) +
                " frames (fault injected by fail_after)");
  if (s.options.stall_after >= 0 && delivered >= s.options.stall_after) {
    std::this_thread::sleep_for(timeout);  // a stalled stream: nothing arrives
    return FrameStatus::kTimeout;
  }
  if (s.ahead) {
    auto got = s.ahead->next(frame, s.truth, timeout);
    if (got && *got == FrameStatus::kFrame) {
      s.depth_from_raw(frame);  // the slots hold raw and colour only (1.5 MB, not 2.1)
      ++s.next_index;
    }
    return got;
  }
  if (s.next_index >= static_cast<std::uint64_t>(s.options.frame_count)) {
    return FrameStatus::kEndOfStream;
  }
  if (auto ok = s.render(s.next_index, frame, s.truth, true, true); !ok) return ok.failure();
  ++s.next_index;
  return FrameStatus::kFrame;
}

Result<std::unique_ptr<SyntheticCamera>> make_synthetic_camera(const FaceModel& model,
                                                               const SyntheticOptions& options) {
  const int V = model.vertex_count;
  if (V <= 0 || model.neutral.size() != static_cast<std::size_t>(3 * V) ||
      model.triangles.empty()) {
    return fail("synthetic: the face model is empty; load data/facemodel.fbfm first");
  }
  if (options.frame_count < 1) return fail("synthetic: frame_count must be at least 1");
  if (!(options.distance_mm >= 500.0 && options.distance_mm <= 4000.0) &&
      options.camera_from_model_track.empty()) {
    return fail("synthetic: distance_mm must be in [500, 4000] (the Kinect's useful range)");
  }
  if (options.identity_coeffs &&
      options.identity_coeffs->size() > static_cast<std::size_t>(model.identity_count)) {
    return fail("synthetic: " + std::to_string(options.identity_coeffs->size()) +
                " identity coefficients given, the model has " +
                std::to_string(model.identity_count));
  }
  auto too_many = [&](const std::vector<float>& w) {
    return w.size() > static_cast<std::size_t>(model.expression_count);
  };
  if (!options.personal_expression_basis.empty() &&
      options.personal_expression_basis.size() != model.expression_basis.size()) {
    return fail("synthetic: personal_expression_basis has " +
                std::to_string(options.personal_expression_basis.size()) +
                " floats; the model's expression basis has " +
                std::to_string(model.expression_basis.size()));
  }
  if (too_many(options.expression_weights) ||
      std::any_of(options.expression_track.begin(), options.expression_track.end(), too_many)) {
    return fail("synthetic: more expression weights than the model's " +
                std::to_string(model.expression_count) + " expressions");
  }

  const KinectRegistration registration(options.calibration);
  auto state = std::make_unique<SyntheticCamera::State>(registration, options);
  SyntheticCamera::State& s = *state;
  if (options.reported_calibration) s.reported_registration.emplace(*options.reported_calibration);
  s.skin_vertex_count = V;
  s.expression_count = model.expression_count;
  std::copy(model.landmark_vertices.begin(), model.landmark_vertices.end(), s.landmarks.begin());

  // Identity: given, or one N(0, 1) draw per mode from the seed.
  std::vector<float> identity;
  if (options.identity_coeffs) {
    identity = *options.identity_coeffs;
  } else {
    identity.resize(static_cast<std::size_t>(model.identity_count));
    for (std::size_t k = 0; k < identity.size(); ++k) {
      identity[k] = static_cast<float>(hashed_gaussian(options.seed, kStreamIdentity, k));
    }
  }
  identity.resize(static_cast<std::size_t>(model.identity_count), 0.0f);
  adjust_identity(options.world, identity);
  s.truth.identity_coeffs = identity;
  s.identity_truth = identity;
  s.identity_mesh.resize(static_cast<std::size_t>(3 * V));
  model.evaluate(identity, {}, s.identity_mesh);
  // Out of the model's span: the displacement is part of the rendered (and true) rest mesh.
  displace_identity(options.world, model, s.identity_mesh);
  s.evaluated.resize(s.identity_mesh.size());
  s.current_weights.assign(static_cast<std::size_t>(model.expression_count), 0.0f);
  std::copy_n(options.expression_weights.begin(), options.expression_weights.size(),
              s.current_weights.begin());
  const std::vector<float>& basis = options.personal_expression_basis.empty()
                                        ? model.expression_basis
                                        : options.personal_expression_basis;
  if (!options.expression_track.empty()) s.expression_basis = basis;

  for (int l = 0; l < 68; ++l) {
    const auto v = s.landmarks[l];
    s.rest_centroid += Eigen::Vector3d(s.identity_mesh[3 * v], s.identity_mesh[3 * v + 1],
                                       s.identity_mesh[3 * v + 2]);
  }
  s.rest_centroid /= 68.0;

  // Rest-pose landmark polygons (model XY) for the cap classification and the albedo painting.
  auto landmark = [&](int l) {
    const auto v = s.landmarks[l];
    return Eigen::Vector3f(s.identity_mesh[3 * v], s.identity_mesh[3 * v + 1],
                           s.identity_mesh[3 * v + 2]);
  };
  auto centroid_of = [&](int first, int last) {
    Eigen::Vector3f c = Eigen::Vector3f::Zero();
    for (int l = first; l <= last; ++l) c += landmark(l);
    return Eigen::Vector3f(c / static_cast<float>(last - first + 1));
  };
  const Eigen::Vector3f right_eye = centroid_of(36, 41), left_eye = centroid_of(42, 47);
  const Eigen::Vector3f mouth = centroid_of(60, 67);

  // Caps over the skin's holes.
  s.triangles = model.triangles;
  for (auto& loop : boundary_loops(model.triangles)) {
    Eigen::Vector3f c = Eigen::Vector3f::Zero();
    for (auto v : loop)
      c += Eigen::Vector3f(s.identity_mesh[3 * v], s.identity_mesh[3 * v + 1],
                           s.identity_mesh[3 * v + 2]);
    c /= static_cast<float>(loop.size());
    Cap cap;
    if ((c - right_eye).norm() < 15.0f || (c - left_eye).norm() < 15.0f) {
      cap.kind = CapKind::kEye;
    } else if ((c - mouth).norm() < 20.0f) {
      cap.kind = CapKind::kMouth;
    } else {
      cap.kind = CapKind::kFlat;
    }
    const auto apex = static_cast<std::uint32_t>(V + s.caps.size());
    // Boundary edge a -> b belongs to a skin triangle; the cap uses b -> a to keep the winding.
    for (std::size_t i = 0; i < loop.size(); ++i) {
      const auto a = loop[i], b = loop[(i + 1) % loop.size()];
      s.triangles.insert(s.triangles.end(), {b, a, apex});
    }
    cap.loop = std::move(loop);
    s.caps.push_back(std::move(cap));
  }
  s.mesh_vertex_count = V + static_cast<int>(s.caps.size());
  s.mesh_triangle_count = static_cast<std::uint32_t>(s.triangles.size() / 3);
  s.model_vertices.resize(s.mesh_vertex_count);
  s.model_normals.resize(s.mesh_vertex_count);
  s.scene_vertices.resize(s.mesh_vertex_count);

  // Wall: a large rectangle facing the camera, fixed in the camera frame.
  if (options.background_mm > 0.0) {
    const auto z = static_cast<float>(options.background_mm), half = 3.0f * z;
    const auto base = static_cast<std::uint32_t>(s.scene_vertices.size());
    s.scene_vertices.emplace_back(-half, -half, z);
    s.scene_vertices.emplace_back(half, -half, z);
    s.scene_vertices.emplace_back(half, half, z);
    s.scene_vertices.emplace_back(-half, half, z);
    for (std::uint32_t i : {0u, 2u, 1u, 0u, 3u, 2u}) s.triangles.push_back(base + i);
  }

  // The static expression (or the first frame's) so model_vertices() is meaningful at once.
  s.set_expression(basis, options.expression_track.empty()
                              ? std::span<const float>(s.current_weights)
                              : std::span<const float>(options.expression_track.front()));

  // Albedo painted on the rest pose (identity, no expression), so it moves with expressions.
  const float skin_tone =
      options.identity_coeffs
          ? 1.0f
          : static_cast<float>(0.8 + 0.3 * hashed_uniform(options.seed, kStreamSkin, 0));
  std::array<Eigen::Vector2f, 5> right_brow, left_brow;
  std::array<Eigen::Vector2f, 6> right_eye_poly, left_eye_poly;
  std::array<Eigen::Vector2f, 12> outer_lip;
  for (int i = 0; i < 5; ++i) right_brow[i] = landmark(17 + i).head<2>();
  for (int i = 0; i < 5; ++i) left_brow[i] = landmark(22 + i).head<2>();
  for (int i = 0; i < 6; ++i) right_eye_poly[i] = landmark(36 + i).head<2>();
  for (int i = 0; i < 6; ++i) left_eye_poly[i] = landmark(42 + i).head<2>();
  for (int i = 0; i < 12; ++i) outer_lip[i] = landmark(48 + i).head<2>();
  // Only vertices on the front of the face get features (the back of the head overlaps in XY).
  const float front_z = std::min({landmark(17).z(), landmark(26).z(), landmark(36).z(),
                                  landmark(45).z(), landmark(48).z(), landmark(54).z()}) -
                        20.0f;
  const double world_tone = options.world.skin_tone >= 0.0
                                ? options.world.skin_tone
                                : hashed_uniform(options.world.seed, kStreamSkin, 1);
  s.skin = options.world.texture ? skin_albedo(world_tone) : Eigen::Vector3f(kSkin * skin_tone);
  s.albedo.assign(s.mesh_vertex_count, s.skin);
  s.brow_weight.assign(static_cast<std::size_t>(V), 0.0f);
  for (int v = 0; v < V; ++v) {
    const Eigen::Vector3f p(s.identity_mesh[3 * v], s.identity_mesh[3 * v + 1],
                            s.identity_mesh[3 * v + 2]);
    if (p.z() < front_z) continue;
    const Eigen::Vector2f q = p.head<2>();
    Eigen::Vector3f colour = s.skin;
    // Brows: 4 mm either side of the landmark polyline, blending out over 2 mm.
    const float brow =
        std::min(polyline_distance(q, right_brow, false), polyline_distance(q, left_brow, false));
    s.brow_weight[v] = std::clamp((6.0f - brow) / 2.0f, 0.0f, 1.0f);
    colour += (kBrow - colour) * s.brow_weight[v];
    // Lips: inside the outer contour, softened over 1 mm at the border.
    const float lip_edge = polyline_distance(q, outer_lip, true);
    const float lip = inside_polygon(q, outer_lip) ? std::clamp(0.5f + lip_edge, 0.0f, 1.0f)
                                                   : std::clamp(0.5f - lip_edge, 0.0f, 1.0f);
    colour += (kLip - colour) * lip;
    // Eyes and lash line: inside the eye contour or within 1.5 mm of it.
    const float eye_edge = std::min(polyline_distance(q, right_eye_poly, true),
                                    polyline_distance(q, left_eye_poly, true));
    const bool in_eye = inside_polygon(q, right_eye_poly) || inside_polygon(q, left_eye_poly);
    colour += (kEye - colour) * (in_eye ? 1.0f : std::clamp((2.5f - eye_edge) / 1.0f, 0.0f, 1.0f));
    s.albedo[v] = colour;
  }
  for (std::size_t c = 0; c < s.caps.size(); ++c) {
    auto& apex = s.albedo[V + c];
    if (s.caps[c].kind == CapKind::kEye) apex = kEye;
    if (s.caps[c].kind == CapKind::kMouth) {
      apex = kMouthInside;
      for (auto v : s.caps[c].loop) s.albedo[v] = 0.5f * (s.albedo[v] + kMouthInside);
    }
  }

  // Hair and beard colour over the painted skin (their depth is degraded per frame).
  s.regions = paint_regions(options.world, model, s.identity_mesh);
  if (options.world.hair || options.world.beard) {
    static const std::array<Eigen::Vector3f, 4> kHair = {rgb(28, 24, 22), rgb(62, 44, 32),
                                                         rgb(105, 74, 48), rgb(168, 134, 92)};
    const auto pick = static_cast<std::size_t>(hashed_uniform(options.world.seed, kStreamSkin, 2) *
                                               (world_tone > 0.6 ? 1.0 : 4.0));
    const Eigen::Vector3f hair = kHair[std::min<std::size_t>(pick, 3)];
    for (int v = 0; v < V; ++v) {
      const float w = std::max(s.regions.hair[v], 0.85f * s.regions.beard[v]);
      s.albedo[v] += (hair - s.albedo[v]) * w;
    }
  }
  // Props after the wall: static ones placed around the face of frame 0.
  if (options.world.any_props()) {
    const Eigen::Vector3f head = s.pose_at(0).apply(s.rest_centroid).cast<float>();
    s.props.emplace(options.world, options.frame_count, head, s.skin);
    s.props->append(s.scene_vertices, s.triangles);
  }

  // Per-frame buffers at their final size, so next_frame() does not allocate.
  const auto k = s.sensor.intrinsics();
  s.truth.landmarks_3d.resize(68);
  s.truth.landmarks_depth_px.resize(68);
  s.truth.landmarks_color_px.resize(68);
  s.truth.noiseless_depth_mm.resize(k.width, k.height);
  s.truth.expression_weights = s.current_weights;

  CameraInfo& info = s.info;
  info.backend = "synthetic";
  info.uri = options.uri.empty() ? "synthetic:seed=" + std::to_string(options.seed) : options.uri;
  info.description = "synthetic Kinect v1: face model, seed " + std::to_string(options.seed) +
                     (options.motion == SyntheticMotion::kHeadTurn ? ", head turn" : ", static") +
                     ", " + std::to_string(options.frame_count) + " frames at " +
                     std::to_string(static_cast<int>(options.distance_mm)) + " mm";
  info.width = k.width;
  info.height = k.height;
  info.fps = kKinectFps;
  info.calibration = options.reported_calibration.value_or(options.calibration);
  info.depth_intrinsics = k;
  info.frame_count = options.frame_count;

  return std::unique_ptr<SyntheticCamera>(new SyntheticCamera(std::move(state)));
}

Result<std::unique_ptr<SyntheticCamera>> make_synthetic_camera(const SyntheticOptions& options) {
  auto model = load_face_model();
  if (!model) {
    return fail("synthetic: cannot load the face model: " + model.error().message);
  }
  return make_synthetic_camera(*model, options);
}

namespace {

Result<std::unique_ptr<DepthCamera>> open_synthetic_with_controls(
    std::string_view arguments, const CameraControls& controls, const CameraResources& resources) {
  if (is_board_target(arguments)) {
    if (!controls.empty()) return fail("synthetic: a calibration board takes no controls");
    return open_board_camera(arguments);  // board_scene.hpp
  }
  // The caller's face model when it lends one (the camera copies what it needs), else our own.
  std::optional<FaceModel> loaded;
  if (resources.face_model == nullptr) {
    auto model = load_face_model();
    if (!model) {
      return fail("synthetic: cannot load the face model: " + model.error().message);
    }
    loaded = std::move(*model);
  }
  const FaceModel& model = resources.face_model != nullptr ? *resources.face_model : *loaded;
  auto options = parse_synthetic_options(arguments, model, controls);
  if (!options) return options.failure();
  options->uri = "synthetic:" + std::string(arguments);
  auto camera = make_synthetic_camera(model, *options);
  if (!camera) return camera.failure();
  return std::unique_ptr<DepthCamera>(std::move(*camera));
}

Result<std::unique_ptr<DepthCamera>> open_synthetic(std::string_view arguments) {
  return open_synthetic_with_controls(arguments, {}, {});
}

std::vector<CameraListing> list_synthetic() {
  return {{"synthetic:",
           "synthetic Kinect v1 rendering of the face model (seed 0, head turn, 90 frames)"}};
}

}  // namespace

CameraBackend synthetic_camera_backend() {
  return {"synthetic",
          &open_synthetic,
          &list_synthetic,
          "synthetic:[seed=N,expr=NAME[:W]+...,motion=headturn|static,frames=N,distance=MM,"
          "noise=on|off,background=MM|off,identity=random|neutral,unit=SEED,reg_dx=PX,reg_dy=PX,"
          "reg_rot=DEG,depth_scale=S,calibrated=0|1,world=realistic|identity|texture|hair|clutter|"
          "noise|unit,world_seed=N,displace=MM,asym=MM,id_scale=S,id_extreme=N,texture=on|off,"
          "tone=T,light=fixed|vary,hair=on|off,beard=on|off,torso=on|off,desk=on|off,hand=on|off,"
          "hand_pass=on|off|START,offset_x=PX,offset_y=PX,block_noise=RAW,block_px=N,speckle=RATE]"
          "  rendered face with ground truth; synthetic:target=checkerboard,board=9x6:25mm[,...]"
          "  a calibration board",
          kSyntheticControls,
          &open_synthetic_with_controls};
}

}  // namespace fb
