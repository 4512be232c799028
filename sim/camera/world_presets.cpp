#include "sim/camera/world_presets.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>

#include "algo/core/mix64.hpp"

namespace fb {
namespace {

double draw(std::uint64_t seed, std::uint64_t k) {
  return static_cast<double>(mix64(mix64(seed * 0x2545F4914F6CDD1Dull + 0x77) + k) >> 11) *
         0x1.0p-53;
}

constexpr const char* kWorldKeys[] = {
    "world",     "world_seed", "displace", "asym",        "id_scale", "id_extreme", "texture",
    "tone",      "light",      "hair",     "beard",       "torso",    "desk",       "hand",
    "hand_pass", "offset_x",   "offset_y", "block_noise", "block_px", "speckle"};

Result<double> number(const std::string& key, const std::string& text, double lo, double hi) {
  double v = 0.0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || end != text.data() + text.size() || !(v >= lo && v <= hi))
    return fail("synthetic: bad value '" + text + "' for " + key + "; expected a number in [" +
                std::to_string(lo) + ", " + std::to_string(hi) + "]");
  return v;
}

Result<bool> on_off(const std::string& key, const std::string& value) {
  if (value == "on" || value == "1") return true;
  if (value == "off" || value == "0") return false;
  return fail("synthetic: bad " + key + " '" + value + "'; expected on or off");
}

}  // namespace

const std::vector<std::string>& world_parts() {
  static const std::vector<std::string> parts = {"identity", "texture", "hair",
                                                 "clutter",  "noise",   "unit"};
  return parts;
}

Result<std::vector<std::string>> scenario_parts(const std::string& scenario) {
  SyntheticOptions probe;
  if (auto ok = apply_world_preset(scenario, 1, probe); !ok) return ok.failure();
  std::vector<std::string> parts;
  if (scenario == "realistic") {
    parts.push_back("baseline");
    for (const auto& p : world_parts()) parts.push_back(p);
  }
  parts.push_back(scenario);
  return parts;
}

Result<void> apply_world_preset(std::string_view part, std::uint64_t seed, SyntheticOptions& o) {
  SyntheticWorld& w = o.world;
  w.seed = seed;
  const bool all = part == "realistic";
  bool known = all || part == "none";
  if (all || part == "identity") {
    w.identity_scale = 1.6;
    w.identity_extreme_modes = 3;
    w.displacement_mm = 2.0 + 3.0 * draw(seed, 1);
    w.asymmetry_mm = 1.0 + 2.0 * draw(seed, 2);
    known = true;
  }
  if (all || part == "texture") {
    w.texture = true;
    w.skin_tone = draw(seed, 3);
    w.light_vary = true;
    known = true;
  }
  if (all || part == "hair") {
    w.hair = true;
    w.beard = seed % 2 == 1;
    known = true;
  }
  if (all || part == "clutter") {
    w.torso = w.desk = w.side_hand = w.hand_pass = true;
    w.offset_x_px = -80.0 + 160.0 * draw(seed, 4);
    w.offset_y_px = -100.0 + 80.0 * draw(seed, 5);
    known = true;
  }
  if (all || part == "noise") {
    o.sensor.correlated_noise_sigma = 0.9;
    o.sensor.correlated_noise_block_px = 6;
    o.sensor.speckle_dropout_rate = 0.005;
    known = true;
  }
  if (all || part == "unit") {
    o.calibration.correction = random_unit_correction(seed + 1);
    KinectCalibration reported = o.calibration;
    reported.correction = RegistrationCorrection{};
    o.reported_calibration = reported;
    known = true;
  }
  if (!known) {
    std::string list;
    for (const auto& p : world_parts()) list += p + "|";
    return fail("synthetic: unknown world '" + std::string(part) + "'; expected realistic|" + list +
                "none");
  }
  return success();
}

bool is_world_key(std::string_view key) {
  return std::find(std::begin(kWorldKeys), std::end(kWorldKeys), key) != std::end(kWorldKeys);
}

Result<void> apply_world_keys(const std::map<std::string, std::string>& values,
                              SyntheticOptions& o) {
  std::uint64_t seed = o.seed;
  if (auto it = values.find("world_seed"); it != values.end()) {
    auto n = number("world_seed", it->second, 0, 1e15);
    if (!n) return n.failure();
    seed = static_cast<std::uint64_t>(*n);
  }
  o.world.seed = seed;
  if (auto it = values.find("world"); it != values.end())
    if (auto ok = apply_world_preset(it->second, seed, o); !ok) return ok;
  SyntheticWorld& w = o.world;
  for (const auto& [key, value] : values) {
    if (key == "world" || key == "world_seed") continue;
    if (!is_world_key(key)) continue;
    auto set_number = [&](double lo, double hi, double& out) -> Result<void> {
      auto n = number(key, value, lo, hi);
      if (!n) return n.failure();
      out = *n;
      return success();
    };
    auto set_flag = [&](bool& out) -> Result<void> {
      auto b = on_off(key, value);
      if (!b) return b.failure();
      out = *b;
      return success();
    };
    Result<void> ok = success();
    double n = 0.0;
    if (key == "displace") ok = set_number(0, 20, w.displacement_mm);
    if (key == "asym") ok = set_number(-20, 20, w.asymmetry_mm);
    if (key == "id_scale") ok = set_number(0, 5, w.identity_scale);
    if (key == "id_extreme") {
      ok = set_number(0, 100, n);
      w.identity_extreme_modes = static_cast<int>(n);
    }
    if (key == "texture") ok = set_flag(w.texture);
    if (key == "tone") ok = set_number(0, 1, w.skin_tone);
    if (key == "light") {
      if (value != "fixed" && value != "vary")
        return fail("synthetic: bad light '" + value + "'; expected fixed or vary");
      w.light_vary = value == "vary";
    }
    if (key == "hair") ok = set_flag(w.hair);
    if (key == "beard") ok = set_flag(w.beard);
    if (key == "torso") ok = set_flag(w.torso);
    if (key == "desk") ok = set_flag(w.desk);
    if (key == "hand") ok = set_flag(w.side_hand);
    if (key == "hand_pass") {
      if (value == "on" || value == "off" || value == "1" || value == "0") {
        ok = set_flag(w.hand_pass);
      } else {
        ok = set_number(0, 1e6, n);
        w.hand_pass = true;
        w.hand_pass_start = static_cast<int>(n);
      }
    }
    if (key == "offset_x") ok = set_number(-300, 300, w.offset_x_px);
    if (key == "offset_y") ok = set_number(-220, 220, w.offset_y_px);
    if (key == "block_noise") ok = set_number(0, 10, o.sensor.correlated_noise_sigma);
    if (key == "block_px") {
      ok = set_number(1, 64, n);
      o.sensor.correlated_noise_block_px = static_cast<int>(n);
    }
    if (key == "speckle") ok = set_number(0, 0.5, o.sensor.speckle_dropout_rate);
    if (!ok) return ok;
  }
  return success();
}

}  // namespace fb
