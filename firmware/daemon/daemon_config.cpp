#include "firmware/daemon/daemon_config.hpp"

#include <toml++/toml.h>

#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <set>
#include <sstream>
#include <utility>

namespace fb {
namespace {

std::filesystem::path default_guide_file() {
  for (const char* dir : {FB_INSTALLED_DATA_DIR, FB_DATA_DIR}) {
    auto p = std::filesystem::path(dir) / "guide_expressions.json";
    std::error_code ec;
    if (std::filesystem::exists(p, ec)) return p;
  }
  return std::filesystem::path(FB_DATA_DIR) / "guide_expressions.json";
}

// Collects the first error while reading typed keys, so each read is one line.
class Reader {
 public:
  Reader(const toml::table& root, std::string origin) : root_(root), origin_(std::move(origin)) {}

  const toml::table* section(std::string_view name) {
    known_sections_.insert(std::string(name));
    const auto* node = root_.get(name);
    if (node == nullptr) return nullptr;
    if (!node->is_table()) {
      error("[" + std::string(name) + "] must be a table");
      return nullptr;
    }
    current_ = std::string(name);
    known_keys_[current_];
    return node->as_table();
  }

  template <class T>
  void read(const toml::table* t, std::string_view key, T& out) {
    if (t == nullptr) return;
    known_keys_[current_].insert(std::string(key));
    const auto* node = t->get(key);
    if (node == nullptr) return;
    if constexpr (std::is_same_v<T, bool>) {
      if (auto v = node->value<bool>()) return void(out = *v);
    } else if constexpr (std::is_integral_v<T>) {
      if (node->is_integer()) {
        // Checked before narrowing: port = 4294967376 must not become port 80.
        const std::int64_t v = *node->value<std::int64_t>();
        if (std::in_range<T>(v)) return void(out = static_cast<T>(v));
        return error(current_ + "." + std::string(key) + " = " + std::to_string(v) +
                     " is out of range");
      }
    } else if constexpr (std::is_floating_point_v<T>) {
      if (auto v = node->value<double>()) {
        // TOML has nan and inf; no threshold or rate means anything as either.
        if (std::isfinite(*v)) return void(out = *v);
        return error(current_ + "." + std::string(key) + " must be a finite number");
      }
    } else if constexpr (std::is_same_v<T, std::filesystem::path>) {
      if (auto v = node->value<std::string>()) return void(out = *v);
    } else {
      if (auto v = node->value<std::string>()) return void(out = *v);
    }
    error(current_ + "." + std::string(key) + " has the wrong type");
  }

  void check_unknown() {
    for (const auto& [name, node] : root_) {
      const std::string section(name.str());
      if (!known_sections_.count(section)) {
        error("unknown section [" + section + "]");
        continue;
      }
      if (!node.is_table()) continue;
      for (const auto& [key, value] : *node.as_table()) {
        if (!known_keys_[section].count(std::string(key.str())))
          error("unknown key " + section + "." + std::string(key.str()));
      }
    }
  }

  void error(const std::string& what) {
    if (first_error_.empty()) first_error_ = origin_ + ": " + what;
  }
  const std::string& first_error() const { return first_error_; }

 private:
  const toml::table& root_;
  std::string origin_;
  std::string current_;
  std::set<std::string> known_sections_;
  std::map<std::string, std::set<std::string>> known_keys_;
  std::string first_error_;
};

// The shortest text that reads back as the same double (0.6, not toml++'s 0.59999999999999998).
std::string shortest_float(double v) {
  char buf[64];
  const auto end = std::to_chars(buf, buf + sizeof buf, v).ptr;
  std::string text(buf, end);
  if (text.find_first_of(".eEn") == std::string::npos) text += ".0";  // TOML floats need a point
  return text;
}

// A TOML basic string. toml++ prints a string with a newline as a multi-line literal ('''...),
// whose first newline the reader drops, so "\n..." did not read back the same.
std::string basic_string(std::string_view text) {
  std::string out = "\"";
  for (const char ch : text) {
    const auto u = static_cast<unsigned char>(ch);
    if (ch == '"' || ch == '\\') {
      out += '\\';
      out += ch;
    } else if (ch == '\n') {
      out += "\\n";
    } else if (u < 0x20 || u == 0x7f) {
      char escape[8];
      std::snprintf(escape, sizeof escape, "\\u%04X", u);
      out += escape;
    } else {
      out += ch;
    }
  }
  return out + "\"";
}

// toml++ prints floats with max_digits10 digits and strings as above; everything else is printed
// by toml++.
std::string print_sections(const toml::table& root) {
  std::ostringstream out;
  bool first = true;
  for (const auto& [name, section] : root) {
    out << (first ? "" : "\n") << "[" << name.str() << "]\n";
    first = false;
    for (const auto& [key, node] : *section.as_table()) {
      out << key.str() << " = ";
      if (const auto* f = node.as_floating_point())
        out << shortest_float(f->get());
      else if (const auto* text = node.as_string())
        out << basic_string(text->get());
      else
        node.visit([&](const auto& value) { out << value; });
      out << "\n";
    }
  }
  return out.str();
}

std::filesystem::path resolve(const std::filesystem::path& p, const std::filesystem::path& base) {
  if (p.empty() || p.is_absolute() || base.empty()) return p;
  return base / p;
}

}  // namespace

DaemonConfig default_daemon_config() {
  DaemonConfig config;
  if (const char* state = std::getenv("STATE_DIRECTORY"); state != nullptr && *state != '\0') {
    // systemd may pass several colon-separated directories; the first is ours.
    std::string first(state);
    config.storage.data_dir = first.substr(0, first.find(':'));
  } else {
    config.storage.data_dir = std::filesystem::current_path() / "facebooth-data";
  }
  config.session.guide_file = default_guide_file();
  return config;
}

Result<DaemonConfig> parse_daemon_config(std::string_view toml_text, std::string_view origin,
                                         const std::filesystem::path& base_dir) {
  toml::table root;
  try {
    root = toml::parse(toml_text, std::string(origin));
  } catch (const toml::parse_error& e) {
    std::ostringstream msg;
    msg << origin << ":" << e.source().begin.line << ":" << e.source().begin.column << ": "
        << e.description();
    return fail(msg.str());
  }
  DaemonConfig c = default_daemon_config();
  Reader r(root, std::string(origin));
  if (auto* t = r.section("camera")) {
    r.read(t, "uri", c.camera.uri);
    r.read(t, "capture_frames", c.camera.capture_frames);
    r.read(t, "preview_fps", c.camera.preview_fps);
    r.read(t, "realtime", c.camera.realtime);
    r.read(t, "synthetic_imitates_guide", c.camera.synthetic_imitates_guide);
    r.read(t, "stored_frame_stride", c.camera.stored_frame_stride);
    r.read(t, "registration_check", c.camera.registration_check);
    r.read(t, "max_misregistration_px", c.camera.max_misregistration_px);
    r.read(t, "self_calibrate", c.camera.self_calibrate);
    r.read(t, "self_calibrate_frames", c.camera.self_calibrate_frames);
  }
  if (auto* t = r.section("gpio")) {
    r.read(t, "backend", c.gpio.backend);
    r.read(t, "chip", c.gpio.chip);
    r.read(t, "main_line", c.gpio.main_line);
    r.read(t, "mode_line", c.gpio.mode_line);
    r.read(t, "led_line", c.gpio.led_line);
    r.read(t, "buttons_active_low", c.gpio.buttons_active_low);
    r.read(t, "debounce_ms", c.gpio.debounce_ms);
    r.read(t, "long_press_ms", c.gpio.long_press_ms);
  }
  if (auto* t = r.section("storage")) {
    std::filesystem::path dir;
    r.read(t, "data_dir", dir);
    if (!dir.empty()) c.storage.data_dir = resolve(dir, base_dir);
  }
  if (auto* t = r.section("http")) {
    r.read(t, "enabled", c.http.enabled);
    r.read(t, "bind", c.http.bind);
    r.read(t, "port", c.http.port);
    r.read(t, "token", c.http.token);
    r.read(t, "token_file", c.http.token_file);
    r.read(t, "threads", c.http.threads);
    c.http.token_file = resolve(c.http.token_file, base_dir);
  }
  if (auto* t = r.section("session")) {
    std::filesystem::path guide;
    r.read(t, "guide_file", guide);
    if (!guide.empty()) c.session.guide_file = resolve(guide, base_dir);
    r.read(t, "min_coverage", c.session.min_coverage);
    r.read(t, "max_residual_mm", c.session.max_residual_mm);
    r.read(t, "min_fused_fraction", c.session.min_fused_fraction);
    r.read(t, "resume", c.session.resume);
    r.read(t, "quick_fit", c.session.quick_fit);
    std::filesystem::path predictor, model;
    r.read(t, "shape_predictor", predictor);
    if (!predictor.empty()) c.session.shape_predictor = resolve(predictor, base_dir);
    r.read(t, "face_model", model);
    if (!model.empty()) c.session.face_model = resolve(model, base_dir);
    r.read(t, "max_fit_rms_mm", c.session.max_fit_rms_mm);
    r.read(t, "max_landmark_error_mm", c.session.max_landmark_error_mm);
    r.read(t, "min_landmark_score", c.session.min_landmark_score);
  }
  if (auto* t = r.section("streaming")) {
    r.read(t, "osc_target", c.streaming.osc_target);
    r.read(t, "vmc_target", c.streaming.vmc_target);
    r.read(t, "save_takes", c.streaming.save_takes);
    r.read(t, "max_take_frames", c.streaming.max_take_frames);
  }
  if (auto* t = r.section("systemd")) r.read(t, "watchdog_divisor", c.watchdog_divisor);
  r.check_unknown();
  if (!r.first_error().empty()) return fail(r.first_error());
  if (auto ok = validate_daemon_config(c); !ok)
    return fail(std::string(origin) + ": " + ok.error().message);
  return c;
}

Result<DaemonConfig> load_daemon_config(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return fail("cannot read config file '" + path.string() + "'");
  std::ostringstream text;
  text << in.rdbuf();
  return parse_daemon_config(text.str(), path.string(), path.parent_path());
}

Result<void> validate_daemon_config(const DaemonConfig& c) {
  if (c.camera.uri.empty()) return fail("camera.uri is empty");
  if (c.camera.capture_frames < 5 || c.camera.capture_frames > 900)
    return fail("camera.capture_frames must be in 5..900 (90 = 3 s at 30 fps)");
  if (!(c.camera.preview_fps >= 0 && c.camera.preview_fps <= 30))
    return fail("camera.preview_fps must be in 0..30");
  if (c.camera.stored_frame_stride < 1) return fail("camera.stored_frame_stride must be >= 1");
  if (!(c.camera.max_misregistration_px > 0 && c.camera.max_misregistration_px <= 20))
    return fail("camera.max_misregistration_px must be in (0, 20] px (3 is the default)");
  if (c.camera.self_calibrate_frames < 10 || c.camera.self_calibrate_frames > 300)
    return fail("camera.self_calibrate_frames must be in 10..300 (45 = 1.5 s at 30 fps)");
  if (c.http.port < 0 || c.http.port > 65535) return fail("http.port must be in 0..65535");
  if (c.http.threads < 2 || c.http.threads > 64)
    return fail("http.threads must be in 2..64 (one is taken by each live-event client)");
  if (c.gpio.debounce_ms < 0 || c.gpio.long_press_ms <= c.gpio.debounce_ms)
    return fail("gpio.long_press_ms must be longer than gpio.debounce_ms");
  if (c.session.min_coverage < 0 || c.session.max_residual_mm <= 0 ||
      c.session.min_fused_fraction < 0 || c.session.min_fused_fraction > 1)
    return fail("session thresholds out of range");
  if (!(c.session.max_fit_rms_mm > 0) || !(c.session.max_landmark_error_mm > 0))
    return fail("session.max_fit_rms_mm and session.max_landmark_error_mm must be > 0");
  if (c.streaming.max_take_frames < 1) return fail("streaming.max_take_frames must be >= 1");
  if (c.storage.data_dir.empty()) return fail("storage.data_dir is empty");
  if (c.watchdog_divisor < 2) return fail("systemd.watchdog_divisor must be at least 2");
  return success();
}

std::string to_toml(const DaemonConfig& c) {
  toml::table root{
      {"camera", toml::table{{"uri", c.camera.uri},
                             {"capture_frames", c.camera.capture_frames},
                             {"preview_fps", c.camera.preview_fps},
                             {"realtime", c.camera.realtime},
                             {"synthetic_imitates_guide", c.camera.synthetic_imitates_guide},
                             {"stored_frame_stride", c.camera.stored_frame_stride},
                             {"registration_check", c.camera.registration_check},
                             {"max_misregistration_px", c.camera.max_misregistration_px},
                             {"self_calibrate", c.camera.self_calibrate},
                             {"self_calibrate_frames", c.camera.self_calibrate_frames}}},
      {"gpio", toml::table{{"backend", c.gpio.backend},
                           {"chip", c.gpio.chip},
                           {"main_line", c.gpio.main_line},
                           {"mode_line", c.gpio.mode_line},
                           {"led_line", c.gpio.led_line},
                           {"buttons_active_low", c.gpio.buttons_active_low},
                           {"debounce_ms", c.gpio.debounce_ms},
                           {"long_press_ms", c.gpio.long_press_ms}}},
      {"storage", toml::table{{"data_dir", c.storage.data_dir.string()}}},
      {"http", toml::table{{"enabled", c.http.enabled},
                           {"bind", c.http.bind},
                           {"port", c.http.port},
                           {"token", c.http.token},
                           {"token_file", c.http.token_file.string()},
                           {"threads", c.http.threads}}},
      {"session", toml::table{{"guide_file", c.session.guide_file.string()},
                              {"min_coverage", c.session.min_coverage},
                              {"max_residual_mm", c.session.max_residual_mm},
                              {"min_fused_fraction", c.session.min_fused_fraction},
                              {"resume", c.session.resume},
                              {"quick_fit", c.session.quick_fit},
                              {"shape_predictor", c.session.shape_predictor.string()},
                              {"face_model", c.session.face_model.string()},
                              {"max_fit_rms_mm", c.session.max_fit_rms_mm},
                              {"max_landmark_error_mm", c.session.max_landmark_error_mm},
                              {"min_landmark_score", c.session.min_landmark_score}}},
      {"streaming", toml::table{{"osc_target", c.streaming.osc_target},
                                {"vmc_target", c.streaming.vmc_target},
                                {"save_takes", c.streaming.save_takes},
                                {"max_take_frames", c.streaming.max_take_frames}}},
      {"systemd", toml::table{{"watchdog_divisor", c.watchdog_divisor}}},
  };
  return print_sections(root);
}

}  // namespace fb
