#include "sim/camera/board_scene.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <numbers>

#include "algo/calibration/registration_model.hpp"
#include "algo/core/mix64.hpp"
#include "drivers/camera/common/camera_uri.hpp"
#include "sim/camera/synthetic_camera.hpp"

namespace fb {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;
constexpr int kSupersample = 8;

// Counter-based uniform in [0, 1) for (seed, stream, k).
double uniform(std::uint64_t seed, std::uint64_t stream, std::uint64_t k) {
  return static_cast<double>(mix64(mix64(seed * 0x9E3779B97F4A7C15ull + stream) + k) >> 11) *
         0x1.0p-53;
}

// Does the whole plate at `pose` project inside the depth image (with a margin), in range?
bool pose_fits(const BoardSpec& board, const RigidPose& pose, const PinholeIntrinsics& k) {
  for (const auto& corner : board.plate_outline()) {
    const Eigen::Vector3d p = pose.apply(corner);
    if (p.z() < 560.0 || p.z() > 1650.0) return false;
    const Eigen::Vector2d px = k.project(p);
    if (px.x() < 30.0 || px.y() < 30.0 || px.x() > k.width - 31.0 || px.y() > k.height - 31.0) {
      return false;
    }
  }
  return true;
}

Result<double> number(const std::string& key, const std::string& text, double lo, double hi) {
  double value = 0.0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || end != text.data() + text.size() || !(value >= lo && value <= hi)) {
    return fail("synthetic checkerboard: bad value '" + text + "' for " + key +
                "; expected a number in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
  }
  return value;
}

constexpr std::string_view kBoardAccepted =
    "accepted with target=checkerboard: board=COLSxROWS:SIZEmm, seed=N, frames=N, noise=on|off, "
    "wall=MM, unit=SEED, reg_dx=PX, reg_dy=PX, reg_rot=DEG, depth_scale=S, calibrated=0|1";

}  // namespace

std::vector<RigidPose> board_scene_poses(const BoardSpec& board, std::uint64_t seed, int count) {
  const PinholeIntrinsics k = KinectCalibration::defaults().depth_intrinsics();
  const Eigen::Vector3d centre((board.cols - 1) * board.square_mm / 2.0,
                               (board.rows - 1) * board.square_mm / 2.0, 0.0);
  std::vector<RigidPose> poses;
  for (int view = 0; view < count; ++view) {
    // Stratified: the 3x3 image cell and the distance band rotate through the views.
    const int cell = view % 9;
    const double band = std::fmod(view * 0.6180339887 + uniform(seed, 7, 0), 1.0);
    RigidPose pose;
    for (int attempt = 0; attempt < 200; ++attempt) {
      const std::uint64_t key = static_cast<std::uint64_t>(view) * 1000 + attempt;
      const double pull = std::min(1.0, attempt / 60.0);  // towards the centre when it won't fit
      const double cu = (cell % 3 + uniform(seed, 1, key)) / 3.0 - 0.5;
      const double cv = (cell / 3 + uniform(seed, 2, key)) / 3.0 - 0.5;
      const double u = k.cx + (1.0 - pull) * cu * (k.width - 120.0);
      const double v = k.cy + (1.0 - pull) * cv * (k.height - 100.0);
      const double z = 600.0 + 900.0 * std::fmod(band + 0.1 * uniform(seed, 3, key), 1.0) *
                                   (attempt < 100 ? 1.0 : 0.5);
      const double tilt = 35.0 * std::sqrt(uniform(seed, 4, key)) * kDeg;
      const double axis = 2.0 * std::numbers::pi * uniform(seed, 5, key);
      const double spin = 15.0 * (2.0 * uniform(seed, 6, key) - 1.0) * kDeg;
      pose.rotation =
          Eigen::AngleAxisd(tilt, Eigen::Vector3d(std::cos(axis), std::sin(axis), 0.0)) *
          Eigen::AngleAxisd(spin, Eigen::Vector3d::UnitZ());
      pose.translation = k.unproject(u, v, z) - pose.rotation * centre;
      if (pose_fits(board, pose, k)) break;
    }
    poses.push_back(pose);
  }
  return poses;
}

struct BoardScene::State {
  State(const BoardSceneOptions& o, const KinectRegistration& truth)
      : options(o),
        sensor(truth, o.sensor),
        model(truth),
        reported(o.reported_calibration.value_or(o.calibration)),
        reported_registration(reported) {}

  BoardSceneOptions options;
  KinectSensorModel sensor;
  RegistrationModel model;  // the unit's true registration
  KinectCalibration reported;
  KinectRegistration reported_registration;
  std::vector<RigidPose> poses;
  SensorFrame sensor_frame;
  std::vector<Eigen::Vector2d> grid_uv;  // colour pixel corners traced to depth pixels
  std::vector<std::int8_t> grid_print;   // print value there (-1: not the plate)

  void render_color(const RigidPose& pose, std::uint64_t noise_seed, ColorImage& color);
  // Traces colour point `c` to the plate; the print value (-1 off the plate), uv updated.
  int trace(const RigidPose& pose, const Eigen::Vector2d& c, Eigen::Vector2d& uv) const;
};

int BoardScene::State::trace(const RigidPose& pose, const Eigen::Vector2d& c,
                             Eigen::Vector2d& uv) const {
  const PinholeIntrinsics& k = sensor.intrinsics();
  const Eigen::Vector3d n = pose.rotation * Eigen::Vector3d::UnitZ();
  const double offset = n.dot(pose.translation);
  auto ray = [&](double u, double v) {
    return Eigen::Vector3d((u - k.cx) / k.fx, (v - k.cy) / k.fy, 1.0);
  };
  auto depth_of = [&](double u, double v) {
    const double d = n.dot(ray(u, v));
    return d > 1e-6 ? offset / d : -1.0;
  };
  if (!model.depth_pixel_of(RegistrationCorrection{}, c, depth_of, uv)) return -1;
  const Eigen::Vector3d p = ray(uv.x(), uv.y()) * depth_of(uv.x(), uv.y());
  const Eigen::Vector3d b = pose.inverse().apply(p);
  return options.board.print_at(b.x(), b.y());
}

void BoardScene::State::render_color(const RigidPose& pose, std::uint64_t noise_seed,
                                     ColorImage& color) {
  const int w = kKinectWidth, h = kKinectHeight;
  color.resize(w, h);
  // Grey levels: a slightly shaded print (brighter when facing the camera) on a mid-grey wall.
  const double facing = std::abs((pose.rotation * Eigen::Vector3d::UnitZ()).z());
  const double level[2] = {25.0 + 10.0 * facing, 170.0 + 60.0 * facing};
  constexpr double kWall = 128.0;
  // Only the plate's neighbourhood needs tracing: its bounding box in colour.
  double x0 = w, y0 = h, x1 = 0, y1 = 0;
  for (const auto& corner : options.board.plate_outline()) {
    const Eigen::Vector3d p = pose.apply(corner);
    Eigen::Vector2d c;
    const Eigen::Vector2d px = sensor.intrinsics().project(p);
    if (!model.color_position(RegistrationCorrection{}, px.x(), px.y(), p.z(), c)) continue;
    x0 = std::min(x0, c.x()), y0 = std::min(y0, c.y());
    x1 = std::max(x1, c.x()), y1 = std::max(y1, c.y());
  }
  const int gx0 = std::clamp(static_cast<int>(x0) - 4, 0, w),
            gx1 = std::clamp(static_cast<int>(x1) + 5, 0, w);
  const int gy0 = std::clamp(static_cast<int>(y0) - 4, 0, h),
            gy1 = std::clamp(static_cast<int>(y1) + 5, 0, h);
  const int gw = gx1 - gx0 + 1;
  grid_uv.assign(static_cast<std::size_t>(gw) * (gy1 - gy0 + 1), Eigen::Vector2d::Zero());
  grid_print.assign(grid_uv.size(), -1);
  const Eigen::Matrix2d inverse = model.mean_jacobian().inverse();
  Eigen::Vector2d q0;
  model.rectified(320.0, 240.0, q0);
  Eigen::Vector2d start =
      Eigen::Vector2d(320.0, 240.0) + inverse * (Eigen::Vector2d(gx0 - 0.5, gy0 - 0.5) - q0);
  // Pixel (x, y) covers [x - 0.5, x + 0.5]; grid point (i, j) is its top-left corner.
  for (int j = 0; j <= gy1 - gy0; ++j) {
    Eigen::Vector2d uv = start;
    for (int i = 0; i < gw; ++i) {
      const std::size_t g = static_cast<std::size_t>(j) * gw + i;
      const Eigen::Vector2d c(gx0 + i - 0.5, gy0 + j - 0.5);
      Eigen::Vector2d traced = uv;
      grid_print[g] = static_cast<std::int8_t>(trace(pose, c, traced));
      if (grid_print[g] >= 0 || (traced - uv).norm() < 50.0) uv = traced;
      grid_uv[g] = uv;
      if (i == 0) start = uv + inverse * Eigen::Vector2d(0.0, 1.0);
    }
  }
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      double value = kWall;
      if (x >= gx0 && x < gx1 && y >= gy0 && y < gy1) {
        const std::size_t g = static_cast<std::size_t>(y - gy0) * gw + (x - gx0);
        const int p[4] = {grid_print[g], grid_print[g + 1], grid_print[g + gw],
                          grid_print[g + gw + 1]};
        auto shade = [&](int print) { return print < 0 ? kWall : level[print]; };
        if (p[0] == p[1] && p[0] == p[2] && p[0] == p[3]) {
          value = shade(p[0]);
        } else {
          double sum = 0.0;
          Eigen::Vector2d uv = grid_uv[g];
          for (int sy = 0; sy < kSupersample; ++sy) {
            for (int sx = 0; sx < kSupersample; ++sx) {
              const Eigen::Vector2d c(x - 0.5 + (sx + 0.5) / kSupersample,
                                      y - 0.5 + (sy + 0.5) / kSupersample);
              Eigen::Vector2d traced = uv;
              sum += shade(trace(pose, c, traced));
            }
          }
          value = sum / (kSupersample * kSupersample);
        }
      }
      // Sensor noise: Box-Muller from two counter-based uniforms per pixel.
      const std::size_t i = static_cast<std::size_t>(y) * w + x;
      const double u1 = std::max(uniform(noise_seed, 11, i), 1e-12),
                   u2 = uniform(noise_seed, 12, i);
      value += 2.0 * std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
      const auto g8 = static_cast<std::uint8_t>(std::clamp(value + 0.5, 0.0, 255.0));
      color.pixels[i] = Rgb8{g8, g8, g8};
    }
  }
}

BoardScene::BoardScene(std::unique_ptr<State> state) : state_(std::move(state)) {}
BoardScene::~BoardScene() = default;

const BoardSceneOptions& BoardScene::options() const {
  return state_->options;
}
const KinectCalibration& BoardScene::reported_calibration() const {
  return state_->reported;
}
int BoardScene::frame_count() const {
  return state_->options.frame_count;
}

Result<std::unique_ptr<BoardScene>> BoardScene::create(const BoardSceneOptions& options) {
  if (options.frame_count < 1) return fail("synthetic checkerboard: frames must be at least 1");
  if (!(options.wall_mm >= 1800.0 && options.wall_mm <= 8000.0)) {
    return fail("synthetic checkerboard: wall must be 1800..8000 mm (behind the farthest board)");
  }
  const KinectRegistration truth(options.calibration);
  auto state = std::make_unique<State>(options, truth);
  state->poses = board_scene_poses(options.board, options.seed, options.frame_count);
  return std::unique_ptr<BoardScene>(new BoardScene(std::move(state)));
}

Result<void> BoardScene::render(int index, RgbdFrame& frame, BoardViewTruth* truth) {
  State& s = *state_;
  if (index < 0 || index >= s.options.frame_count) {
    return fail("synthetic checkerboard: view " + std::to_string(index) + " out of range");
  }
  const RigidPose& pose = s.poses[static_cast<std::size_t>(index)];
  std::vector<Eigen::Vector3f> vertices;
  for (const auto& corner : s.options.board.plate_outline()) {
    vertices.push_back(pose.apply(corner).cast<float>());
  }
  const auto wall = static_cast<float>(s.options.wall_mm), half = 3.0f * wall;
  vertices.insert(
      vertices.end(),
      {{-half, -half, wall}, {half, -half, wall}, {half, half, wall}, {-half, half, wall}});
  const std::vector<std::uint32_t> triangles = {0, 2, 1, 0, 3, 2, 4, 6, 5, 4, 7, 6};
  const std::uint64_t noise_seed = mix64(mix64(s.options.seed) + static_cast<std::uint64_t>(index));
  if (auto captured = s.sensor.capture(vertices, triangles, noise_seed, s.sensor_frame);
      !captured) {
    return captured.failure();
  }
  const int w = kKinectWidth, h = kKinectHeight;
  frame.index = static_cast<std::uint64_t>(index);
  frame.depth_host_time_s = frame.color_host_time_s = index / kKinectFps;
  frame.depth_device_timestamp = frame.color_device_timestamp =
      static_cast<std::uint32_t>(index * 2'000'000ull);
  frame.raw_disparity = s.sensor_frame.raw;
  frame.depth_mm.resize(w, h);
  s.reported_registration.disparity_to_mm(frame.raw_disparity, frame.depth_mm);
  s.render_color(pose, noise_seed, frame.color);
  if (truth != nullptr) {
    truth->camera_from_board = pose;
    truth->corners_color.clear();
    truth->corners_depth.clear();
    for (int j = 0; j < s.options.board.corner_count(); ++j) {
      const Eigen::Vector3d p = pose.apply(s.options.board.corner(j));
      const Eigen::Vector2d px = s.sensor.intrinsics().project(p);
      Eigen::Vector2d c = Eigen::Vector2d::Constant(-1.0);
      s.model.color_position(RegistrationCorrection{}, px.x(), px.y(), p.z(), c);
      truth->corners_depth.push_back(px);
      truth->corners_color.push_back(c);
    }
  }
  return success();
}

bool is_board_target(std::string_view arguments) {
  auto values = parse_key_values(arguments);
  if (!values) return false;
  const auto it = values->find("target");
  return it != values->end() && it->second == "checkerboard";
}

Result<BoardSceneOptions> parse_board_scene_options(std::string_view arguments) {
  auto values = parse_key_values(arguments);
  if (!values)
    return fail("synthetic: " + values.error().message + "; " + std::string(kBoardAccepted));
  BoardSceneOptions options;
  RegistrationCorrection& unit = options.calibration.correction;
  bool decalibrated = false;
  int calibrated = -1;
  for (const auto& [key, value] : *values) {
    Result<double> n = 0.0;
    if (key == "target") {
      if (value != "checkerboard") {
        return fail("synthetic: target must be checkerboard (or absent for the face), got '" +
                    value + "'");
      }
      continue;
    } else if (key == "board") {
      auto board = parse_board_spec(value);
      if (!board) return board.failure();
      options.board = *board;
      continue;
    } else if (key == "noise") {
      if (value != "on" && value != "off") {
        return fail("synthetic checkerboard: bad noise '" + value + "'; expected on or off");
      }
      options.sensor.depth_noise = value == "on";
      continue;
    } else if (key == "calibrated") {
      if (value != "0" && value != "1") {
        return fail("synthetic checkerboard: bad calibrated '" + value + "'; expected 0 or 1");
      }
      calibrated = value == "1" ? 1 : 0;
      continue;
    }
    if (key == "seed" || key == "unit") {
      n = number(key, value, 0, 1e15);
    } else if (key == "frames") {
      n = number(key, value, 1, 10000);
    } else if (key == "wall") {
      n = number(key, value, 1800, 8000);
    } else if (key == "reg_dx" || key == "reg_dy") {
      n = number(key, value, -40, 40);
    } else if (key == "reg_rot") {
      n = number(key, value, -5, 5);
    } else if (key == "depth_scale") {
      n = number(key, value, 0.8, 1.2);
    } else {
      return fail("synthetic: unknown option '" + key + "'; " + std::string(kBoardAccepted));
    }
    if (!n) return n.failure();
    if ((key == "seed" || key == "unit" || key == "frames") && *n != std::floor(*n)) {
      return fail("synthetic checkerboard: " + key + " must be a whole number, got '" + value +
                  "'");
    }
    if (key == "seed") options.seed = static_cast<std::uint64_t>(*n);
    if (key == "frames") options.frame_count = static_cast<int>(*n);
    if (key == "wall") options.wall_mm = *n;
    if (key == "unit") unit = random_unit_correction(static_cast<std::uint64_t>(*n));
    if (key == "reg_dx") unit.dx_px = *n;
    if (key == "reg_dy") unit.dy_px = *n;
    if (key == "reg_rot") unit.rotation_deg = *n;
    if (key == "depth_scale") unit.depth_scale = *n;
    decalibrated = decalibrated || (key != "seed" && key != "frames" && key != "wall");
  }
  // A decalibrated unit reports the plain defaults, as a Kinect without a device.json does.
  if ((decalibrated && calibrated != 1) || calibrated == 0) {
    KinectCalibration reported = options.calibration;
    reported.correction = RegistrationCorrection{};
    options.reported_calibration = reported;
  }
  options.uri = "synthetic:" + std::string(arguments);
  return options;
}

namespace {

class BoardCamera : public DepthCamera {
 public:
  explicit BoardCamera(std::unique_ptr<BoardScene> scene) : scene_(std::move(scene)) {
    const auto& o = scene_->options();
    info_.uri = o.uri;
    info_.backend = "synthetic";
    info_.description = "synthetic Kinect v1: checkerboard " + o.board.to_string() + ", seed " +
                        std::to_string(o.seed) + ", " + std::to_string(o.frame_count) + " views";
    info_.calibration = scene_->reported_calibration();
    info_.depth_intrinsics = info_.calibration.depth_intrinsics();
    info_.frame_count = o.frame_count;
  }
  const CameraInfo& info() const override { return info_; }
  Result<void> start() override {
    started_ = true;
    next_ = 0;
    return success();
  }
  void stop() override { started_ = false; }
  Result<FrameStatus> next_frame(RgbdFrame& frame, std::chrono::milliseconds) override {
    if (!started_) return fail("synthetic: next_frame() called before start()");
    if (next_ >= scene_->frame_count()) return FrameStatus::kEndOfStream;
    if (auto rendered = scene_->render(next_, frame); !rendered) return rendered.failure();
    ++next_;
    return FrameStatus::kFrame;
  }

 private:
  std::unique_ptr<BoardScene> scene_;
  CameraInfo info_;
  bool started_ = false;
  int next_ = 0;
};

}  // namespace

Result<std::unique_ptr<DepthCamera>> open_board_camera(std::string_view arguments) {
  auto options = parse_board_scene_options(arguments);
  if (!options) return options.failure();
  auto scene = BoardScene::create(*options);
  if (!scene) return scene.failure();
  return std::unique_ptr<DepthCamera>(new BoardCamera(std::move(*scene)));
}

}  // namespace fb
