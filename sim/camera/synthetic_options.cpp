// The synthetic camera's URI (`synthetic:seed=3,expr=...`) and camera controls parsed into
// SyntheticOptions; a decalibrated unit drawn from its seed.
#include <charconv>
#include <cmath>
#include <map>
#include <string>

#include "algo/core/mix64.hpp"
#include "drivers/camera/common/camera_uri.hpp"
#include "sim/camera/expressive_track.hpp"
#include "sim/camera/synthetic_camera.hpp"
#include "sim/camera/world_presets.hpp"
#include "storage/asset_files.hpp"

namespace fb {
namespace {

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

}  // namespace fb
