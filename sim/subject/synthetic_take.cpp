#include "sim/camera/frame_truth.hpp"
#include "sim/subject/synthetic_take.hpp"

#include <algorithm>
#include <cmath>
#include <memory>
#include <random>
#include <set>
#include <string>

#include "algo/render/kinect_sensor.hpp"
#include "algo/tracking/arkit.hpp"
#include "algo/tracking/face_tracker.hpp"
#include "sim/camera/world_presets.hpp"

namespace fb::cli {
namespace {

// The gaze shapes are not animated in the takes: eyeLook* turn the eyeballs, which are not in
// the skin mesh, and what they do to the lids eyeWide and eyeBlink also do, so the tracker
// holds them (WeightSolverOptions::hold_gaze_shapes). They are still scored (truth 0).
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

}  // namespace

Result<RenderedTake> render_take(const FaceModel& model, const TakeSpec& spec) {
  RenderedTake out;
  out.take = make_take(model, spec);
  if (!spec.world.empty())
    if (auto ok = apply_world_preset(spec.world, spec.seed, out.take.options); !ok)
      return ok.failure();
  auto calibration = unit_calibration_for(model, out.take.options, spec.unit_calibration);
  if (!calibration) return calibration.failure();
  auto camera = make_synthetic_camera(model, out.take.options);
  if (!camera) return camera.failure();
  if (auto started = (*camera)->start(); !started) return started.failure();
  out.intrinsics = (*camera)->info().depth_intrinsics;
  out.calibration = *calibration;
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
    const FrameTruth& truth = *frame_truth(**camera);
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

}  // namespace fb::cli
