// Building a synthetic camera: the subject's identity mesh, caps over the skin's holes, the
// wall, the painted albedo (brows, lips, eyes, hair) and the per-frame buffers.
#include <algorithm>
#include <array>
#include <limits>
#include <map>
#include <string>

#include "sim/camera/synthetic_camera_state.hpp"
#include "storage/asset_files.hpp"

namespace fb {
namespace {

using namespace synthetic_detail;

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

using State = SyntheticCamera::State;

// Inconsistent options (bad sizes, frame_count < 1, distance out of range) against `model`.
Result<void> check_options(const FaceModel& model, const SyntheticOptions& options) {
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
  return success();
}

// Rest-pose landmark `l` of the subject (identity applied, no expression).
Eigen::Vector3f landmark_at_rest(const State& s, int l) {
  const auto v = s.landmarks[l];
  return Eigen::Vector3f(s.identity_mesh[3 * v], s.identity_mesh[3 * v + 1],
                         s.identity_mesh[3 * v + 2]);
}

Eigen::Vector3f landmark_centroid(const State& s, int first, int last) {
  Eigen::Vector3f c = Eigen::Vector3f::Zero();
  for (int l = first; l <= last; ++l) c += landmark_at_rest(s, l);
  return Eigen::Vector3f(c / static_cast<float>(last - first + 1));
}

// The subject's identity mesh (out-of-span displacement included), the weights and the rest
// centroid the head turns about.
void set_identity(State& s, const FaceModel& model, const SyntheticOptions& options,
                  const std::vector<float>& basis) {
  const int V = model.vertex_count;
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
  if (!options.expression_track.empty()) s.expression_basis = basis;

  for (int l = 0; l < 68; ++l) {
    const auto v = s.landmarks[l];
    s.rest_centroid += Eigen::Vector3d(s.identity_mesh[3 * v], s.identity_mesh[3 * v + 1],
                                       s.identity_mesh[3 * v + 2]);
  }
  s.rest_centroid /= 68.0;
}

// Caps over the skin's holes (eyes, mouth, neck), then the wall behind the head.
void add_caps_and_wall(State& s, const FaceModel& model, const SyntheticOptions& options) {
  const int V = model.vertex_count;
  // Rest-pose landmark centroids (model XY) for the cap classification.
  const Eigen::Vector3f right_eye = landmark_centroid(s, 36, 41),
                        left_eye = landmark_centroid(s, 42, 47);
  const Eigen::Vector3f mouth = landmark_centroid(s, 60, 67);

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
}

// The face's features painted on the rest pose (identity, no expression), so they move with
// expressions: brows, lips and eyes from the landmark polylines, the caps' insides.
void paint_features(State& s, const FaceModel& model, const SyntheticOptions& options,
                    double world_tone) {
  const int V = model.vertex_count;
  auto landmark = [&](int l) { return landmark_at_rest(s, l); };
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
}

// Hair and beard colour over the painted skin (their depth is degraded per frame).
void paint_hair(State& s, const FaceModel& model, const SyntheticOptions& options,
                double world_tone) {
  const int V = model.vertex_count;
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
}

// Per-frame buffers at their final size, so next_frame() does not allocate; the camera's info.
void finish_info(State& s, const SyntheticOptions& options) {
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
}

}  // namespace

Result<std::unique_ptr<SyntheticCamera>> make_synthetic_camera(const FaceModel& model,
                                                               const SyntheticOptions& options) {
  if (auto ok = check_options(model, options); !ok) return ok.failure();
  const KinectRegistration registration(options.calibration);
  auto state = std::make_unique<SyntheticCamera::State>(registration, options);
  SyntheticCamera::State& s = *state;
  if (options.reported_calibration) s.reported_registration.emplace(*options.reported_calibration);
  s.skin_vertex_count = model.vertex_count;
  s.expression_count = model.expression_count;
  std::copy(model.landmark_vertices.begin(), model.landmark_vertices.end(), s.landmarks.begin());
  const std::vector<float>& basis = options.personal_expression_basis.empty()
                                        ? model.expression_basis
                                        : options.personal_expression_basis;
  set_identity(s, model, options, basis);
  add_caps_and_wall(s, model, options);

  // The static expression (or the first frame's) so model_vertices() is meaningful at once.
  s.set_expression(basis, options.expression_track.empty()
                              ? std::span<const float>(s.current_weights)
                              : std::span<const float>(options.expression_track.front()));

  const double world_tone = options.world.skin_tone >= 0.0
                                ? options.world.skin_tone
                                : hashed_uniform(options.world.seed, kStreamSkin, 1);
  paint_features(s, model, options, world_tone);
  paint_hair(s, model, options, world_tone);
  // Props after the wall: static ones placed around the face of frame 0.
  if (options.world.any_props()) {
    const Eigen::Vector3f head = s.pose_at(0).apply(s.rest_centroid).cast<float>();
    s.props.emplace(options.world, options.frame_count, head, s.skin);
    s.props->append(s.scene_vertices, s.triangles);
  }

  finish_info(s, options);
  return std::unique_ptr<SyntheticCamera>(new SyntheticCamera(std::move(state)));
}

Result<std::unique_ptr<SyntheticCamera>> make_synthetic_camera(const SyntheticOptions& options) {
  auto model = load_face_model();
  if (!model) {
    return fail("synthetic: cannot load the face model: " + model.error().message);
  }
  return make_synthetic_camera(*model, options);
}

}  // namespace fb
