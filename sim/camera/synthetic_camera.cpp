#include "sim/camera/synthetic_camera.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <string>
#include <thread>

#include "algo/core/mix64.hpp"
#include "sim/camera/board_scene.hpp"
#include "sim/camera/color_fill.hpp"
#include "sim/camera/render_ahead.hpp"
#include "sim/camera/synthetic_camera_state.hpp"
#include "sim/camera/world_presets.hpp"
#include "storage/asset_files.hpp"

namespace fb {

using namespace synthetic_detail;

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;
// 60 MHz device clock at 30 fps.
constexpr std::uint32_t kTicksPerFrame = 2'000'000;

}  // namespace

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
