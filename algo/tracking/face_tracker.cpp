#include "algo/tracking/face_tracker.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <numeric>
#include <unordered_map>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <Eigen/SVD>

#include "algo/tracking/depth_filter.hpp"
#include "algo/tracking/occlusion_report.hpp"
#include "algo/tracking/weight_uncertainty.hpp"

namespace fb {

const char* to_string(TrackState state) {
  switch (state) {
    case TrackState::kSearching:
      return "searching";
    case TrackState::kCalibrating:
      return "calibrating";
    case TrackState::kTracking:
      return "tracking";
    case TrackState::kRecovered:
      return "recovered";
    case TrackState::kLost:
      return "lost";
    case TrackState::kBadInput:
      return "bad_input";
  }
  return "unknown";
}

namespace {

using Clock = std::chrono::steady_clock;
using RowMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using ColMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::ColMajor>;

double ms_since(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

// A float rigid transform for the hot loops: p_camera = r * p_model + t.
struct Pose {
  Eigen::Matrix3f r = Eigen::Matrix3f::Identity();
  Eigen::Vector3f t = Eigen::Vector3f::Zero();
  // The small motion (omega, dt) about `pivot` (camera frame): x' = Rw (x - pivot) + pivot + dt.
  void apply_twist(const Eigen::Vector3f& omega, const Eigen::Vector3f& dt,
                   const Eigen::Vector3f& pivot) {
    const float angle = omega.norm();
    const Eigen::Matrix3f rw = angle > 1e-9f
                                   ? Eigen::AngleAxisf(angle, omega / angle).toRotationMatrix()
                                   : Eigen::Matrix3f::Identity();
    r = rw * r;
    t = rw * (t - pivot) + pivot + dt;
  }
  RigidPose to_rigid() const {
    RigidPose p;
    p.rotation = Eigen::Quaterniond(r.cast<double>()).normalized();
    p.translation = t.cast<double>();
    return p;
  }
  static Pose from(const RigidPose& p) {
    return {p.rotation.normalized().toRotationMatrix().cast<float>(), p.translation.cast<float>()};
  }
};

// Pixel rectangle [x0, x1) x [y0, y1).
using Box = PixelRect;

// Tukey biweight: (1 - (r/c)^2)^2 inside the cut-off, 0 outside.
inline float tukey(float r, float c) {
  const float u = r / c;
  if (u * u >= 1.0f) return 0.0f;
  const float s = 1.0f - u * u;
  return s * s;
}

// 4-lane float / int vectors (GCC vector extensions; SSE on x86, NEON on ARM).
using V4f = float __attribute__((vector_size(16)));
using V4i = int __attribute__((vector_size(16)));
using V4u16 = std::uint16_t __attribute__((vector_size(8)));

// 4 consecutive depth pixels (mm) as floats.
inline V4f load4(const std::uint16_t* p) {
  V4u16 packed;
  std::memcpy(&packed, p, sizeof packed);
  return __builtin_convertvector(packed, V4f);
}

const Eigen::Matrix3f kFlip = Eigen::Vector3f(1.0f, -1.0f, -1.0f).asDiagonal();

// gram = A^T A for A = rows [first, first + count), in chunks of rows: Eigen's GEMM packs its
// operands into a workspace that it heap-allocates above 128 KB (EIGEN_STACK_ALLOCATION_LIMIT);
// 256 x 53 floats stay on the stack, so the steady state does not allocate (and it is no
// slower). A symmetric rank-k update (SYRK) builds the lower triangle only, half the
// multiply-adds of the full product; the upper triangle is then mirrored (the solver reads
// whole columns).
void set_gram(const RowMatrix& rows, int first, int count, ShapeMatrix& gram) {
  constexpr int kChunkRows = 256;
  gram.setZero();
  for (int start = first; start < first + count; start += kChunkRows) {
    const int n = std::min(kChunkRows, first + count - start);
    gram.selfadjointView<Eigen::Lower>().rankUpdate(rows.middleRows(start, n).transpose());
  }
  gram = gram.selfadjointView<Eigen::Lower>();
}

}  // namespace

struct FaceTracker::State {
  const FaceModel* model = nullptr;  // non-owning; create() documents the lifetime
  TrackerOptions options;
  PinholeIntrinsics intrinsics;
  float fx = 0, fy = 0, cx = 0, cy = 0;
  int width = 0, height = 0;
  int k = 0;  // fitting shapes
  int n = 0;  // samples
  int modes = 0;

  std::vector<std::uint32_t> sample_vertices;
  // Identity-independent: expression deltas and identity modes at the samples (3n x k, 3n x m).
  // The deltas by column: update_current() adds only the shapes with a non-zero weight.
  ColMatrix expression_at_samples;
  RowMatrix identity_at_samples;
  RowMatrix expression_at_landmarks;  // 3*68 x k
  RowMatrix identity_at_landmarks;    // 3*68 x m
  // The model's own expression deltas; a stored rig (set_rig) replaces the two above.
  ColMatrix model_expression_at_samples;
  RowMatrix model_expression_at_landmarks;
  bool custom_rig = false;
  const SubjectBlendshapes* subject_blendshapes = nullptr;  // see set_subject_blendshapes()

  // The subject's rig (rebuilt by build_rig()).
  std::vector<float> identity;           // m coefficients
  Eigen::VectorXf base;                  // 3n: neutral + identity at the samples
  std::vector<Eigen::Vector3f> normals;  // n, model frame, of the identity neutral
  RowMatrix normal_rows;                 // n x k: n_i^T B_i (point-to-plane rows)
  Eigen::VectorXf landmark_base;         // 3*68, with landmark_offset
  // The subject's landmark offsets (model frame, 3*68), measured while calibrating: where the
  // detector puts each point on this face relative to the model's landmark vertex.
  Eigen::VectorXf landmark_offset;
  Eigen::Vector3f centroid = Eigen::Vector3f::Zero();  // of the samples, model frame
  ShapeVector shape_ridge;     // per-shape Tikhonov weight (mm^2), see build_rig()
  ShapeVector shape_sparsity;  // per-shape L1 weight (mm^2) of the frame, see solve_weights()
  float signal_median = 1.0f;  // median depth signal H_jj of the shapes over the whole face
  ShapeVector full_signal;     // per shape: H_jj over the whole face
  ShapeVector seen_fraction;   // per shape: the last frame's H_jj / full_signal (clamped to 1)
  std::vector<int> weak_shapes;
  std::vector<std::uint8_t> gaze_shape;          // per shape: an eyeLook* (gaze) shape
  std::vector<std::pair<int, int>> antagonists;  // shape pairs, TrackerOptions::antagonist_weight
  float nose_z = 0.0f;                           // largest model z of the samples
  bool calibrated = false;

  // Per-frame state.
  Eigen::VectorXf current;           // 3n: base + B w
  Eigen::VectorXf landmark_current;  // 3*68
  ShapeVector weights;               // the current solution
  ShapeVector previous_weights;      // last frame's output
  Pose pose;                         // raw ICP pose
  bool have_pose = false;
  Pose last_good_pose;
  bool have_last_good = false;
  bool lost = false;
  double last_time = 0.0;
  bool have_time = false;
  PoseFilter filter;
  RigidPose filtered;

  // Depth ring buffer and the smoothed face box.
  std::vector<DepthImage> ring;
  int ring_count = 0;
  int ring_head = -1;
  Image<float> smoothed;
  Image<float> spatial_scratch;  // the spatial pass's output before it replaces `smoothed`
  Box box;

  // Weight solve buffers.
  RowMatrix rows;  // (n + 2*68) x k
  Eigen::VectorXf targets;
  std::vector<int> found_sample;      // n: samples with a depth correspondence this round
  std::vector<float> found_residual;  // their point-to-plane residuals (model frame)
  std::vector<float> found_target;    // n_i . (q - base_i)
  std::vector<float> abs_scratch;     // |residual| for the median
  // Samples behind an occluder on this frame (mark_occluded()); honoured while mask_on.
  std::vector<std::uint8_t> occluded;
  // The same for the 68 landmarks: a detector's points under a hand sit on the hand.
  std::array<std::uint8_t, 68> landmark_occluded{};
  bool mask_on = false;
  OcclusionState occlusion;  // what the report says (held while the face is searched for)
  ShapeMatrix h;
  ShapeVector g;
  ShapeMatrix h_hidden;  // imputed rows of the hidden samples, see solve_weights()
  // TrackerOptions::report_weight_sigma: the frame's Fisher information and what it implies.
  ShapeMatrix information;
  ShapeMatrix landmark_gram;
  ShapeVector weight_sigma;

  // Calibration frames.
  std::vector<Image<float>> calib_depth;
  std::vector<Box> calib_box;
  std::vector<Pose> calib_pose;
  std::vector<ShapeVector> calib_weights;
  std::vector<Eigen::Vector2f> calib_landmarks;    // calibration_frames x 68
  std::vector<std::uint8_t> calib_landmark_valid;  // calibration_frames x 68
  std::vector<float> calib_landmark_scale;         // per calibration frame: landmark_scale()
  int calib_count = 0;
  std::vector<float> mesh_scratch;
  std::vector<Eigen::Vector3f> mesh_normals;

  // --- helpers ---
  // Rigid part of each identity mode at the samples ([omega; t] about `rigid_pivot`, 6 x m),
  // removed from the calibration basis: depth of the front of the face cannot tell a head
  // rotated by a degree from a differently shaped head, so calibrated identities carry no
  // rigid motion and the pose is determined by the data alone.
  Eigen::Matrix<float, 6, Eigen::Dynamic> rigid_of_mode;
  Eigen::Vector3f rigid_pivot = Eigen::Vector3f::Zero();
  using Twist = Eigen::Matrix<float, 6, 1>;
  void build_rig(std::span<const float> coefficients, const Twist& rigid_offset = Twist::Zero());
  // The rest of build_rig() once mesh_scratch holds the subject's neutral (full mesh).
  void finish_rig();
  void use_model_expressions() {
    if (!custom_rig) return;
    expression_at_samples = model_expression_at_samples;
    expression_at_landmarks = model_expression_at_landmarks;
    custom_rig = false;
  }
  // With a subject_blendshapes source: its deltas for the identity in `identity` (mesh_scratch
  // holds that identity's neutral).
  void build_subject_blendshapes();
  void update_current() {
    // current = base + B w over the shapes with w_j != 0 (w >= 0 with an L1 prior: most are
    // exactly 0, and the others add exactly what the full product adds, up to rounding).
    current = base;
    for (int j = 0; j < k; ++j) {
      if (weights[j] != 0.0f) current.noalias() += weights[j] * expression_at_samples.col(j);
    }
    landmark_current = landmark_base;
    landmark_current.noalias() += expression_at_landmarks * weights;
  }
  Eigen::Vector3f sample(int i) const { return current.segment<3>(3 * i); }
  bool depth_at(const Image<float>& image, const Box& b, float u, float v, float& z) const;
  // Sample i's point x and normal nn in the camera frame under pose p; false when it faces away
  // from the camera or grazes it (depth there is unreliable).
  bool facing_sample(const Pose& p, int i, Eigen::Vector3f& x, Eigen::Vector3f& nn) const {
    x = p.r * sample(i) + p.t;
    nn = p.r * normals[static_cast<std::size_t>(i)];
    return x.z() > 1.0f && nn.dot(x) <= -0.2f * x.norm();
  }
  // d proj / d x at the camera-frame point x (2x3): the point's image motion per unit motion.
  Eigen::Matrix<float, 2, 3> projection_jacobian(const Eigen::Vector3f& x) const {
    const float iz = 1.0f / x.z();
    Eigen::Matrix<float, 2, 3> j;
    j << fx * iz, 0.0f, -fx * x.x() * iz * iz, 0.0f, fy * iz, -fy * x.y() * iz * iz;
    return j;
  }
  // How much a source's landmark rows count against the ones the weights are set for.
  float landmark_scale(const TrackLandmarks& l) const {
    if (l.noise_px <= 0.0f) return 1.0f;
    const float ratio = options.landmark_noise_px / l.noise_px;
    return ratio * ratio;
  }
  // The pixel (u, v) the camera-frame point x (z > 0) projects to.
  Eigen::Vector2f pixel_of(const Eigen::Vector3f& x) const {
    return {fx * x.x() / x.z() + cx, fy * x.y() / x.z() + cy};
  }
  // Landmark l of the current face (landmark_current) in the camera frame at pose p.
  Eigen::Vector3f landmark_in_camera(const Pose& p, int l) const {
    return p.r * landmark_current.segment<3>(3 * l) + p.t;
  }
  // The measured point q on the camera ray through x (depth_at() at x's pixel), if any.
  bool measured_point(const Image<float>& image, const Box& b, const Eigen::Vector3f& x,
                      Eigen::Vector3f& q) const {
    float z = 0.0f;
    const Eigen::Vector2f px = pixel_of(x);
    if (!depth_at(image, b, px.x(), px.y(), z)) return false;
    q = x * (z / x.z());
    return true;
  }
  Box predicted_box(const Pose& p) const;
  int smooth(const DepthImage& depth, const Box& b);
  void smooth_spatially(const Box& b);
  struct IcpStats {
    int facing = 0;
    int hidden = 0;  // facing samples inside the image the occlusion mask hides
    int used = 0;
    int inliers = 0;
    float rms = 0.0f;
  };
  void mark_occluded(const Image<float>& image, const Box& b, const Pose& p,
                     const TrackLandmarks* landmarks);
  IcpStats icp(const Image<float>& image, const Box& b, Pose& p, int iterations, float first_gate,
               float gate) const;
  // `iterations` IRLS rounds; the frame's last solve (final) records each shape's seen
  // fraction for the next frame.
  void solve_weights(const Image<float>& image, const Box& b, const Pose& p, int iterations,
                     bool final, const TrackLandmarks* landmarks, int& landmarks_used);
  // `face_seen`: landmarks say there is a face here (see max_rms_mm()).
  bool acceptable(const IcpStats& s, bool acquiring, bool face_seen) const;
  // The RMS bound of a fit: before calibration the model is the mean face, which fits an
  // atypical one only to a few mm, so the bound is looser there when landmarks confirm a face
  // (depth alone cannot tell a face at 5 mm from a head-sized ellipsoid).
  float max_rms_mm(bool face_seen) const {
    return calibrated || !face_seen ? options.max_rms_mm : options.uncalibrated_max_rms_mm;
  }
  bool acquire(const TrackLandmarks* landmarks, IcpStats& stats);
  // Returns the mean RMS of the calibration frames re-tracked with the fitted face.
  float calibrate();
  void calibrate_landmark_offsets();
  void calibrate_depth_offsets();
  void output(TrackReport& report, double time_s);
  // TrackerOptions::report_weight_sigma, from the frame's last weight solve: its depth rows
  // [0, depth_rows) with noise depth_sigma_mm, then its landmark rows.
  void estimate_weight_sigma(int depth_rows, int landmark_rows, float depth_sigma_mm);
};

void FaceTracker::State::build_rig(std::span<const float> coefficients, const Twist& rigid_offset) {
  identity.assign(std::max<std::size_t>(static_cast<std::size_t>(modes), coefficients.size()),
                  0.0f);
  std::copy(coefficients.begin(), coefficients.end(), identity.begin());
  // Full-mesh neutral of this identity for the normals (area-weighted vertex normals).
  const FaceModel& m = *model;
  mesh_scratch.resize(static_cast<std::size_t>(3 * m.vertex_count));
  m.evaluate(identity, {}, mesh_scratch);
  if (!rigid_offset.isZero()) {
    // Minus the linearised rigid motion: v -= omega x (mean_v - pivot) + t.
    const Eigen::Vector3f omega = rigid_offset.head<3>(), t = rigid_offset.tail<3>();
    for (int v = 0; v < m.vertex_count; ++v) {
      const Eigen::Vector3f mean(m.neutral[3 * v], m.neutral[3 * v + 1], m.neutral[3 * v + 2]);
      const Eigen::Vector3f d = omega.cross(mean - rigid_pivot) + t;
      for (int a = 0; a < 3; ++a) mesh_scratch[3 * v + a] -= d[a];
    }
  }
  finish_rig();
}

void FaceTracker::State::build_subject_blendshapes() {
  if (subject_blendshapes == nullptr) return;
  use_model_expressions();  // the source overwrites the shapes it knows
  auto build = [&](auto& matrix, std::span<const std::uint32_t> vertices) {
    ColMatrix deltas = matrix;  // the layout SubjectBlendshapes writes
    subject_blendshapes->subject_deltas(
        identity, vertices,
        std::span<float>(deltas.data(), static_cast<std::size_t>(deltas.size())));
    matrix = deltas;
  };
  build(expression_at_samples, sample_vertices);
  build(expression_at_landmarks, model->landmark_vertices);
  custom_rig = true;  // reset() and the next identity start from the model's deltas again
  finish_rig();
  update_current();
}

void FaceTracker::State::finish_rig() {
  const FaceModel& m = *model;
  mesh_normals.assign(static_cast<std::size_t>(m.vertex_count), Eigen::Vector3f::Zero());
  auto vertex = [&](std::uint32_t v) {
    return Eigen::Vector3f(mesh_scratch[3 * v], mesh_scratch[3 * v + 1], mesh_scratch[3 * v + 2]);
  };
  for (std::size_t t = 0; t + 2 < m.triangles.size(); t += 3) {
    const auto a = m.triangles[t], b = m.triangles[t + 1], cc = m.triangles[t + 2];
    const Eigen::Vector3f nn = (vertex(b) - vertex(a)).cross(vertex(cc) - vertex(a));
    mesh_normals[a] += nn;
    mesh_normals[b] += nn;
    mesh_normals[cc] += nn;
  }
  base.resize(3 * n);
  normals.resize(static_cast<std::size_t>(n));
  centroid.setZero();
  nose_z = -std::numeric_limits<float>::infinity();
  for (int i = 0; i < n; ++i) {
    const auto v = sample_vertices[static_cast<std::size_t>(i)];
    base.segment<3>(3 * i) = vertex(v);
    normals[static_cast<std::size_t>(i)] = mesh_normals[v].normalized();
    centroid += vertex(v);
    nose_z = std::max(nose_z, vertex(v).z());
  }
  centroid /= static_cast<float>(n);
  // Point-to-plane rows of the weight solve: n_i . (B_i w). With the normals of the neutral
  // they do not depend on the pose (n_camera . R B_i w = n_model . B_i w).
  normal_rows.resize(n, k);
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3f& nn = normals[static_cast<std::size_t>(i)];
    normal_rows.row(i) = nn.x() * expression_at_samples.row(3 * i) +
                         nn.y() * expression_at_samples.row(3 * i + 1) +
                         nn.z() * expression_at_samples.row(3 * i + 2);
  }
  landmark_base.resize(3 * 68);
  for (int l = 0; l < 68; ++l) landmark_base.segment<3>(3 * l) = vertex(m.landmark_vertices[l]);
  landmark_base += landmark_offset;
  // Depth signal of each shape: H0_jj = sum_i (n_i . B_ij)^2. Shapes far below the median are
  // nearly invisible in depth and would wander on noise, and the gaze shapes alias the lids
  // (see TrackerOptions::hold_gaze_shapes), so they get a strong prior to 0.
  const Eigen::VectorXf signal = normal_rows.colwise().squaredNorm().transpose();
  std::vector<float> sorted(signal.data(), signal.data() + k);
  std::nth_element(sorted.begin(), sorted.begin() + k / 2, sorted.end());
  const float median = sorted[static_cast<std::size_t>(k / 2)];
  shape_ridge.resize(k);
  shape_sparsity.resize(k);
  signal_median = median;
  full_signal = signal.cwiseMax(1e-6f);
  seen_fraction = ShapeVector::Ones(k);
  weak_shapes.clear();
  for (int j = 0; j < k; ++j) {
    const bool weak = (options.hold_gaze_shapes && gaze_shape[static_cast<std::size_t>(j)]) ||
                      signal[j] < options.weak_shape_fraction * median;
    shape_ridge[j] = options.ridge + (weak ? options.weak_shape_ridge * median : 0.0f);
    if (weak) weak_shapes.push_back(j);
  }
  update_current();
}

bool FaceTracker::State::depth_at(const Image<float>& image, const Box& b, float u, float v,
                                  float& z) const {
  // Bilinear between the 4 pixel centres around (u, v) when all are valid and on one surface.
  const int x0 = static_cast<int>(std::floor(u)), y0 = static_cast<int>(std::floor(v));
  if (x0 < b.x0 || y0 < b.y0 || x0 + 1 >= b.x1 || y0 + 1 >= b.y1) return false;
  const float* row0 = &image.pixels[static_cast<std::size_t>(y0) * width + x0];
  const float* row1 = row0 + width;
  const float d00 = row0[0], d10 = row0[1], d01 = row1[0], d11 = row1[1];
  if (d00 <= 0.0f || d10 <= 0.0f || d01 <= 0.0f || d11 <= 0.0f) return false;
  const float lo = std::min(std::min(d00, d10), std::min(d01, d11));
  const float hi = std::max(std::max(d00, d10), std::max(d01, d11));
  if (hi - lo > 12.0f) return false;
  const float ax = u - x0, ay = v - y0;
  z = (1 - ay) * ((1 - ax) * d00 + ax * d10) + ay * ((1 - ax) * d01 + ax * d11);
  return true;
}

Box FaceTracker::State::predicted_box(const Pose& p) const {
  float u0 = 1e9f, v0 = 1e9f, u1 = -1e9f, v1 = -1e9f;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3f x = p.r * sample(i) + p.t;
    if (x.z() <= 1.0f) continue;
    const Eigen::Vector2f px = pixel_of(x);
    const float u = px.x(), v = px.y();
    u0 = std::min(u0, u), u1 = std::max(u1, u), v0 = std::min(v0, v), v1 = std::max(v1, v);
  }
  constexpr int kMargin = 16;  // px: a frame's motion plus the bilinear footprint
  Box b;
  b.x0 = std::clamp(static_cast<int>(u0) - kMargin, 0, width);
  b.y0 = std::clamp(static_cast<int>(v0) - kMargin, 0, height);
  b.x1 = std::clamp(static_cast<int>(u1) + kMargin, 0, width);
  b.y1 = std::clamp(static_cast<int>(v1) + kMargin, 0, height);
  return b;
}

int FaceTracker::State::smooth(const DepthImage& depth, const Box& b) {
  // Weighted temporal mean: w_a = decay^a * (1 - (d_a - d_0)^2 / range^2)^2 for frames that
  // agree with the newest within `range`; the newest frame defines validity.
  // Branch-free, 4 pixels at a time (GCC vector extensions: SSE on the host, NEON on the
  // device), the row's remainder one at a time; the arithmetic and its order per pixel are
  // the same in both, so the result does not depend on the grouping.
  const int count = std::min(ring_count, 16);
  const float range = options.temporal_range_mm, inv_range2 = 1.0f / (range * range);
  const float lo = options.min_depth_mm, hi = options.max_depth_mm;
  std::array<const std::uint16_t*, 16> frames{};
  std::array<float, 16> decay{};
  for (int a = 0; a < count; ++a) {
    const int slot =
        (ring_head - a + static_cast<int>(ring.size())) % static_cast<int>(ring.size());
    frames[a] = a == 0 ? depth.pixels.data() : ring[static_cast<std::size_t>(slot)].pixels.data();
    decay[a] = std::pow(options.temporal_decay, static_cast<float>(a));
  }
  const V4f zero4 = {0.0f, 0.0f, 0.0f, 0.0f}, one4 = {1.0f, 1.0f, 1.0f, 1.0f};
  V4i valid4 = {0, 0, 0, 0};  // -1 per valid pixel
  int valid = 0;
  for (int y = b.y0; y < b.y1; ++y) {
    const std::size_t row = static_cast<std::size_t>(y) * width;
    float* out = smoothed.pixels.data() + row;
    int x = b.x0;
    for (; x + 4 <= b.x1; x += 4) {
      const V4f d0 = load4(frames[0] + row + x);
      V4f sum = d0, wsum = one4;
      for (int a = 1; a < count; ++a) {
        const V4f d = load4(frames[a] + row + x);
        const V4f diff = d - d0;
        const V4f q = diff * diff * inv_range2;
        const V4f t = decay[a] * (1.0f - q) * (1.0f - q);
        const V4f w = (d > 0.0f) & (q < 1.0f) ? t : zero4;
        sum += w * d;
        wsum += w;
      }
      const V4i ok = (d0 >= lo) & (d0 <= hi);
      const V4f mean = sum / wsum;  // wsum >= 1
      const V4f result = ok ? mean : zero4;
      std::memcpy(out + x, &result, sizeof result);
      valid4 += ok;
    }
    for (; x < b.x1; ++x) {
      const std::size_t i = row + static_cast<std::size_t>(x);
      const float d0 = frames[0][i];
      if (!(d0 >= lo && d0 <= hi)) {
        out[x] = 0.0f;
        continue;
      }
      float sum = d0, wsum = 1.0f;
      for (int a = 1; a < count; ++a) {
        const float d = frames[a][i];
        const float diff = d - d0;
        const float q = diff * diff * inv_range2;
        if (d <= 0.0f || q >= 1.0f) continue;
        const float w = decay[a] * (1.0f - q) * (1.0f - q);
        sum += w * d;
        wsum += w;
      }
      out[x] = sum / wsum;
      ++valid;
    }
  }
  return valid - (valid4[0] + valid4[1] + valid4[2] + valid4[3]);
}

void FaceTracker::State::smooth_spatially(const Box& b) {
  const int r = options.spatial_radius_px;
  // A box too small for the window has no interior (edge_aware_mean writes nothing either).
  if (r <= 0 || b.x1 - b.x0 <= 2 * r || b.y1 - b.y0 <= 2 * r) return;
  edge_aware_mean(smoothed, b, {.radius_px = r, .range_mm = options.spatial_range_mm},
                  spatial_scratch);
  for (int y = b.y0 + r; y < b.y1 - r; ++y) {
    const auto first = static_cast<std::ptrdiff_t>(y) * width + b.x0 + r;
    std::copy(spatial_scratch.pixels.begin() + first,
              spatial_scratch.pixels.begin() + first + (b.x1 - b.x0 - 2 * r),
              smoothed.pixels.begin() + first);
  }
}

void FaceTracker::State::mark_occluded(const Image<float>& image, const Box& b, const Pose& p,
                                       const TrackLandmarks* landmarks) {
  // Visibility: a sample is hidden when the depth at its pixel, or at one of 8 pixels
  // occluder_radius_px away, is nearer than the model point by more than occluder_margin_mm:
  // something (a hand) is in front of the face there. The margin is above the face's own
  // relief (the nose stands ~30 mm off the cheeks), so the face never hides itself. Hidden
  // samples leave the pose, the weights and the robust scale: the occluder's residuals
  // (centimetres) would otherwise inflate the MAD and so the Tukey cut-off, and the face
  // samples along its rim (mixed depths, the projector shadow's edge) would pass the cut-off
  // and drag both. Made once per frame from the predicted pose.
  const float margin = options.occluder_margin_mm;
  mask_on = margin > 0.0f;
  if (!mask_on) return;
  // Pass 1, the sample's own pixel; pass 2 (only when pass 1 found an occluder: the common
  // unoccluded frame pays one read a sample) the 8 pixels around it.
  const int r = std::max(0, options.occluder_radius_px);
  const std::array<std::array<int, 2>, 8> offsets = {
      {{-r, 0}, {r, 0}, {0, -r}, {0, r}, {-r, -r}, {r, -r}, {-r, r}, {r, r}}};
  auto nearer_at = [&](int px, int py, float nearer) {
    if (px < b.x0 || py < b.y0 || px >= b.x1 || py >= b.y1) return false;
    const float d = image.pixels[static_cast<std::size_t>(py) * width + px];
    return d > 0.0f && d < nearer;
  };
  auto pixel = [&](int i, int& u, int& v, float& nearer) {
    const Eigen::Vector3f x = p.r * sample(i) + p.t;
    if (x.z() <= 1.0f) return false;
    const Eigen::Vector2f px = pixel_of(x);
    u = static_cast<int>(std::lround(px.x()));
    v = static_cast<int>(std::lround(px.y()));
    nearer = x.z() - margin;
    return true;
  };
  bool any = false;
  for (int i = 0; i < n; ++i) {
    int u = 0, v = 0;
    float nearer = 0.0f;
    const bool hidden = pixel(i, u, v, nearer) && nearer_at(u, v, nearer);
    occluded[static_cast<std::size_t>(i)] = hidden ? 1 : 0;
    any = any || hidden;
  }
  landmark_occluded.fill(0);
  if (!any) return;
  // A landmark is hidden by the same test at its model point or at the detected point (a
  // detector's point on the hand has the hand's depth): own pixel and the 8 around it.
  const bool detected = landmarks != nullptr && landmarks->points.size() >= 68;
  auto hidden_around = [&](int u, int v, float nearer) {
    if (nearer_at(u, v, nearer)) return true;
    for (std::size_t o = 0; o < offsets.size() && r > 0; ++o)
      if (nearer_at(u + offsets[o][0], v + offsets[o][1], nearer)) return true;
    return false;
  };
  for (int l = 0; l < 68; ++l) {
    const Eigen::Vector3f x = landmark_in_camera(p, l);
    if (x.z() <= 1.0f) continue;
    const float nearer = x.z() - margin;
    const Eigen::Vector2f px = pixel_of(x);
    bool hidden = hidden_around(static_cast<int>(std::lround(px.x())),
                                static_cast<int>(std::lround(px.y())), nearer);
    if (!hidden && detected) {
      const Eigen::Vector2f& q = landmarks->points[static_cast<std::size_t>(l)];
      hidden = hidden_around(static_cast<int>(std::lround(q.x())),
                             static_cast<int>(std::lround(q.y())), nearer);
    }
    landmark_occluded[static_cast<std::size_t>(l)] = hidden ? 1 : 0;
  }
  // A shape predictor places its points jointly: with most of the inner face covered, the
  // points that look free are placed by the covered ones too, so none is used.
  const int hidden_inner =
      std::accumulate(landmark_occluded.begin() + 17, landmark_occluded.end(), 0);
  if (hidden_inner > options.max_hidden_landmark_fraction * 51.0f) landmark_occluded.fill(1);
  if (r == 0) return;
  for (int i = 0; i < n; ++i) {
    auto& hidden = occluded[static_cast<std::size_t>(i)];
    int u = 0, v = 0;
    float nearer = 0.0f;
    if (hidden || !pixel(i, u, v, nearer)) continue;
    for (const auto& [dx, dy] : offsets) {
      if (nearer_at(u + dx, v + dy, nearer)) {
        hidden = 1;
        break;
      }
    }
  }
}

FaceTracker::State::IcpStats FaceTracker::State::icp(const Image<float>& image, const Box& b,
                                                     Pose& p, int iterations, float first_gate,
                                                     float gate) const {
  IcpStats stats;
  for (int it = 0; it < iterations; ++it) {
    // Gate shrinks geometrically from first_gate to gate over the first iterations.
    const float c = std::max(gate, first_gate * std::pow(0.5f, static_cast<float>(it)));
    const Eigen::Vector3f pivot = p.r * centroid + p.t;
    Eigen::Matrix<float, 6, 6> jtj = Eigen::Matrix<float, 6, 6>::Zero();
    Eigen::Matrix<float, 6, 1> jtr = Eigen::Matrix<float, 6, 1>::Zero();
    IcpStats s;
    double r2 = 0.0;
    for (int i = 0; i < n; ++i) {
      Eigen::Vector3f x, nn, q;
      if (!facing_sample(p, i, x, nn)) continue;
      const Eigen::Vector2f px = pixel_of(x);
      const float u = px.x(), v = px.y();
      if (u < 0.0f || v < 0.0f || u > width - 1.0f || v > height - 1.0f) continue;
      // Hidden samples are not expected to be seen: the inlier fraction of loss detection is of
      // the visible ones (min_inliers still reports a face covered entirely).
      if (mask_on && occluded[static_cast<std::size_t>(i)]) {
        ++s.hidden;
        continue;
      }
      ++s.facing;
      if (!measured_point(image, b, x, q)) continue;
      ++s.used;
      const float r = nn.dot(x - q);
      const float w = tukey(r, c);
      if (w <= 0.0f) continue;
      ++s.inliers;
      r2 += static_cast<double>(r) * r;
      Eigen::Matrix<float, 6, 1> j;
      j.head<3>() = (x - pivot).cross(nn);
      j.tail<3>() = nn;
      jtj.noalias() += w * j * j.transpose();
      jtr.noalias() += w * r * j;
    }
    s.rms = s.inliers > 0 ? static_cast<float>(std::sqrt(r2 / s.inliers)) : 1e9f;
    stats = s;
    if (s.inliers < 12) break;
    jtj.diagonal().array() += 1e-3f;
    const Eigen::Matrix<float, 6, 1> xi = jtj.ldlt().solve(-jtr);
    p.apply_twist(xi.head<3>(), xi.tail<3>(), pivot);
    const float angle = xi.head<3>().norm();
    // Orthonormalise now and then against float drift.
    if (it == iterations - 1) p.r = Eigen::Quaternionf(p.r).normalized().toRotationMatrix();
    if (angle < options.icp_converged_rad && xi.tail<3>().norm() < options.icp_converged_mm &&
        it > 0)
      break;
  }
  return stats;
}

void FaceTracker::State::solve_weights(const Image<float>& image, const Box& b, const Pose& p,
                                       int iterations, bool final, const TrackLandmarks* landmarks,
                                       int& landmarks_used) {
  const Eigen::Matrix3f rt = p.r.transpose();
  for (int it = 0; it < iterations; ++it) {
    int found = 0;
    for (int i = 0; i < n; ++i) {
      Eigen::Vector3f x, nn, measured;
      if (!facing_sample(p, i, x, nn)) continue;
      if (mask_on && occluded[static_cast<std::size_t>(i)]) continue;
      if (!measured_point(image, b, x, measured)) continue;
      // Data point in the model frame; the row says n_i . (B_i w) = n_i . (q - base_i).
      const Eigen::Vector3f xm = sample(i);
      const Eigen::Vector3f& nm = normals[static_cast<std::size_t>(i)];
      const Eigen::Vector3f q = rt * (measured - p.t);
      const auto f = static_cast<std::size_t>(found++);
      found_sample[f] = i;
      found_residual[f] = nm.dot(xm - q);
      found_target[f] = nm.dot(q - base.segment<3>(3 * i));
    }
    // Robust scale: Tukey cut-off c = k * 1.4826 * median|r| (the MAD estimate of the noise
    // sigma, with the median of the current residuals centred at ~0), clamped to
    // [weight_min_gate_mm, icp_gate_mm]. An occluder's samples (residuals of centimetres) and
    // the ragged edges around it (a few mm) then get zero weight, while the clean face, whose
    // residual spread is the sensor noise, keeps its full weight.
    float cutoff = options.icp_gate_mm;
    float noise_sigma = 0.0f;  // the MAD estimate
    if ((options.weight_tukey_k > 0.0f || options.report_weight_sigma) && found > 16) {
      for (int f = 0; f < found; ++f)
        abs_scratch[static_cast<std::size_t>(f)] =
            std::abs(found_residual[static_cast<std::size_t>(f)]);
      auto mid = abs_scratch.begin() + found / 2;
      std::nth_element(abs_scratch.begin(), mid, abs_scratch.begin() + found);
      noise_sigma = 1.4826f * *mid;
    }
    if (options.weight_tukey_k > 0.0f && noise_sigma > 0.0f) {
      cutoff = std::clamp(options.weight_tukey_k * noise_sigma, options.weight_min_gate_mm,
                          options.icp_gate_mm);
    }
    int count = 0;
    for (int f = 0; f < found; ++f) {
      const auto fi = static_cast<std::size_t>(f);
      const float w = tukey(found_residual[fi], cutoff);
      if (w <= 0.0f) continue;
      const float s = std::sqrt(w);
      rows.row(count) = s * normal_rows.row(found_sample[fi]);
      targets[count] = s * found_target[fi];
      ++count;
    }
    const int depth_rows = count;
    landmarks_used = 0;
    if (landmarks != nullptr && landmarks->points.size() >= 68) {
      const float lw = options.landmark_weight * landmark_scale(*landmarks);
      for (int l = 17; l < 68; ++l) {
        if (!landmarks->valid.empty() && !landmarks->valid[static_cast<std::size_t>(l)]) continue;
        if (mask_on && landmark_occluded[static_cast<std::size_t>(l)]) continue;
        const Eigen::Vector3f x = landmark_in_camera(p, l);
        if (x.z() <= 1.0f) continue;
        const Eigen::Vector2f r = pixel_of(x) - landmarks->points[static_cast<std::size_t>(l)];
        const float rn = r.norm();
        const float hw = rn < options.landmark_huber_px ? 1.0f : options.landmark_huber_px / rn;
        // d proj / d x times R: the landmark's image motion per model-frame motion.
        const Eigen::Matrix<float, 2, 3> jr = projection_jacobian(x) * p.r;
        const float s = std::sqrt(lw * hw);
        for (int a = 0; a < 2; ++a) {
          // Linearised at the current w: J w_new = J w - r.
          rows.row(count) = s * (jr(a, 0) * expression_at_landmarks.row(3 * l) +
                                 jr(a, 1) * expression_at_landmarks.row(3 * l + 1) +
                                 jr(a, 2) * expression_at_landmarks.row(3 * l + 2));
          targets[count] = rows.row(count).dot(weights) - s * r[a];
          ++count;
        }
        ++landmarks_used;
      }
    }
    if (count < 8) return;
    // Samples under an occluder are imputed at the previous frame's weights with weight
    // hidden_hold: rows n_i . B_i (w - w_prev) = 0. A shape mostly under the plate then holds
    // instead of following the few samples of it still in view, which otherwise pull it (and,
    // through the shared samples, the visible shapes) to whatever fits the plate's ragged edge.
    int hidden_rows = 0;
    if (mask_on && options.hidden_hold > 0.0f) {
      const float s = std::sqrt(options.hidden_hold);
      for (int i = 0; i < n; ++i) {
        if (!occluded[static_cast<std::size_t>(i)]) continue;
        Eigen::Vector3f x, nn;
        if (!facing_sample(p, i, x, nn)) continue;
        rows.row(count + hidden_rows++) = s * normal_rows.row(i);
      }
    }
    set_gram(rows, 0, count, h);
    g.noalias() = rows.topRows(count).transpose() * targets.head(count);
    if (hidden_rows > 0) set_gram(rows, count, hidden_rows, h_hidden);
    if (options.report_weight_sigma && final && it == iterations - 1 && noise_sigma > 0.0f)
      estimate_weight_sigma(depth_rows, count - depth_rows, noise_sigma);
    // The data rows are in mm^2 and the L1 weight was set for the sensor's usual noise: a
    // noisier frame (correlated disparity noise, a worse unit, hair) gives each mm^2 less
    // evidence, so the L1 weight grows with the frame's noise variance (MAD) over the reference.
    float prior_scale = 1.0f;
    if (options.prior_noise_reference_mm > 0.0f && noise_sigma > 0.0f) {
      const float ratio = noise_sigma / options.prior_noise_reference_mm;
      prior_scale = std::clamp(ratio * ratio, 1.0f, options.max_prior_noise_scale);
    }
    // The L1 weight follows the signal this frame's rows give each shape: a shape whose region
    // is hidden (an occluder, the far side of a turned head) has no data, and a weight sized for
    // the whole face would drive it to 0 against the temporal term within a frame or two.
    // A low-signal shape that was on in the previous frame keeps a lighter one (see
    // TrackerOptions::on_shape_sparsity).
    for (int j = 0; j < k; ++j) {
      const bool continuing = previous_weights[j] > options.on_shape_min_weight &&
                              full_signal[j] < options.on_shape_max_signal * signal_median;
      shape_sparsity[j] =
          prior_scale * options.sparsity *
          std::pow(std::max(h(j, j), 0.0f) / signal_median, options.sparsity_signal_power) *
          (continuing ? options.on_shape_sparsity : 1.0f);
    }
    const float lt = options.temporal_weight;
    if (options.stale_temporal_floor < 1.0f) {
      // A shape hidden on the previous frame (seen_fraction: its signal then over its
      // whole-face signal) only held its value: the temporal term gets that fraction of its
      // weight (at least the floor), so a region coming out from under an occluder follows its
      // data at once. The ridge scales with this frame's fraction, so a hidden shape holds
      // (shape_ridge = ridge + the weak-shape prior; only the ridge part scales).
      for (int j = 0; j < k; ++j) {
        const float now = std::clamp(h(j, j) / full_signal[j], 0.0f, 1.0f);
        const float ltj = lt * std::clamp(seen_fraction[j], options.stale_temporal_floor, 1.0f);
        h(j, j) += ltj + shape_ridge[j] - options.ridge * (1.0f - now);
        g[j] += ltj * previous_weights[j];
        if (final && it == iterations - 1) seen_fraction[j] = now;  // read above
      }
    } else {
      h.diagonal().array() += lt + shape_ridge.array();
      g += lt * previous_weights;
    }
    g -= shape_sparsity;
    if (hidden_rows > 0) {
      h += h_hidden;
      g.noalias() += h_hidden * previous_weights;
    }
    for (const auto& [a, b] : antagonists) {
      // + mu w_a w_b in the cost: w >= 0, so it only charges the two being on together.
      const float mu = options.antagonist_weight * std::sqrt(h(a, a) * h(b, b));
      h(a, b) += mu;
      h(b, a) += mu;
    }
    solve_bounded_lsq(h, g, 0.0f, 1.0f, weights);
    if (options.support_sparsity < 1.0f) {
      // Relaxed lasso: the L1 term chose which shapes are on; on those it would also bias the
      // weight down by ~sparsity / H_jj (0.1-0.3 for a brow or lid, whose depth signal H_jj is
      // 45-300 mm^2), so they are solved again with the L1 weight scaled by support_sparsity.
      for (int j = 0; j < k; ++j)
        if (weights[j] > 0.0f) g[j] += (1.0f - options.support_sparsity) * shape_sparsity[j];
      solve_bounded_lsq(h, g, 0.0f, 1.0f, weights);
    }
    update_current();
  }
}

bool FaceTracker::State::acceptable(const IcpStats& s, bool acquiring, bool face_seen) const {
  // Acquisition is stricter on coverage (a flat wall must not pass for a face).
  const float fraction =
      acquiring ? std::max(0.5f, options.min_inlier_fraction) : options.min_inlier_fraction;
  const float rms = max_rms_mm(face_seen);
  return s.inliers >= options.min_inliers &&
         static_cast<float>(s.inliers) >= fraction * static_cast<float>(s.facing) && s.rms <= rms;
}

bool FaceTracker::State::acquire(const TrackLandmarks* landmarks, IcpStats& stats) {
  // Candidate starting poses, best evidence first: a pose from the landmarks (detection on the
  // colour image), the last good pose (a short occlusion), and a frontal face on the nearest
  // surface (depth detection) at three yaws.
  std::array<Pose, 5> candidates;
  int count = 0;
  const Box full{0, 0, width, height};
  bool from_landmarks = false;
  if (landmarks != nullptr && landmarks->points.size() >= 68) {
    // Kabsch between the model landmarks and the landmarks lifted with the depth.
    Eigen::Matrix<float, 3, 68> src, dst;
    int m = 0;
    for (int l = 17; l < 68; ++l) {
      if (!landmarks->valid.empty() && !landmarks->valid[static_cast<std::size_t>(l)]) continue;
      const Eigen::Vector2f& px = landmarks->points[static_cast<std::size_t>(l)];
      float z = 0.0f;
      if (!depth_at(smoothed, full, px.x(), px.y(), z)) continue;
      src.col(m) = landmark_current.segment<3>(3 * l);
      dst.col(m) = Eigen::Vector3f((px.x() - cx) * z / fx, (px.y() - cy) * z / fy, z);
      ++m;
    }
    if (m >= 10) {
      const Eigen::Matrix3f t = Eigen::umeyama(src.leftCols(m), dst.leftCols(m), false)
                                    .topLeftCorner<4, 4>()
                                    .eval()
                                    .block<3, 3>(0, 0);
      Pose p;
      p.r = t;
      const Eigen::Vector3f sc = src.leftCols(m).rowwise().mean();
      const Eigen::Vector3f dc = dst.leftCols(m).rowwise().mean();
      p.t = dc - p.r * sc;
      candidates[count++] = p;
      from_landmarks = true;
    }
  }
  // A detection says where the face is now; the last good pose where it was.
  if (have_last_good) candidates[count++] = last_good_pose;
  {
    // Nearest surface: a 1 cm depth histogram of every 4th pixel; the first bin with a few
    // dozen samples is the front of the nearest object (the face, for a seated subject).
    std::array<int, 256> histogram{};
    const float lo = options.min_depth_mm;
    for (int y = 0; y < height; y += 4) {
      for (int x = 0; x < width; x += 4) {
        const float d = smoothed.pixels[static_cast<std::size_t>(y) * width + x];
        if (d <= 0.0f) continue;
        const int bin = std::clamp(static_cast<int>((d - lo) / 10.0f), 0, 255);
        ++histogram[static_cast<std::size_t>(bin)];
      }
    }
    int bin = 0;
    while (bin < 256 && histogram[static_cast<std::size_t>(bin)] < 20) ++bin;
    if (bin < 256) {
      const float front = lo + 10.0f * bin;
      double su = 0, sv = 0, sz = 0;
      int m = 0;
      for (int y = 0; y < height; y += 2) {
        for (int x = 0; x < width; x += 2) {
          const float d = smoothed.pixels[static_cast<std::size_t>(y) * width + x];
          if (d <= 0.0f || d > front + options.acquire_band_mm) continue;
          su += x, sv += y, sz += d;
          ++m;
        }
      }
      if (m > 50) {
        const float z = static_cast<float>(sz / m);
        const Eigen::Vector3f centre(static_cast<float>((su / m - cx) * z / fx),
                                     static_cast<float>((sv / m - cy) * z / fy), z);
        for (float yaw_deg : {0.0f, 25.0f, -25.0f}) {
          if (count >= static_cast<int>(candidates.size())) break;
          Pose p;
          p.r = kFlip * Eigen::AngleAxisf(yaw_deg * std::numbers::pi_v<float> / 180.0f,
                                          Eigen::Vector3f::UnitY())
                            .toRotationMatrix();
          // Samples' centroid at the blob centre in x, y; the nose tip on the nearest surface.
          p.t = centre - p.r * centroid;
          const Eigen::Vector3f nose =
              centroid + Eigen::Vector3f(0.0f, 0.0f, nose_z - centroid.z());
          p.t.z() = front - (p.r * nose).z();
          candidates[count++] = p;
        }
      }
    }
  }
  // Acquisition accepts only a fit as good as tracking gives: most of the face's samples on the
  // surface (a face rotated far from the truth shows too few) with a residual near the sensor
  // noise (ICP can converge to a wrong rotation at the right place with a few mm RMS). Before
  // calibration the mean face fits a real one only to a few mm, so the RMS bound is then
  // acceptable()'s alone (the tracking one, or uncalibrated_max_rms_mm when landmarks confirm a
  // face).
  auto good = [&](const IcpStats& s) {
    return acceptable(s, true, from_landmarks) &&
           static_cast<float>(s.inliers) >= options.acquire_min_sample_fraction * n &&
           (!calibrated || s.rms <= options.acquire_max_rms_mm);
  };
  // With landmarks, a candidate must also put the model's landmarks on them: median
  // reprojection error over the interior points.
  auto landmark_error_px = [&](const Pose& p) {
    std::array<float, 68> errors{};
    int m = 0;
    for (int l = 17; l < 68; ++l) {
      if (!landmarks->valid.empty() && !landmarks->valid[static_cast<std::size_t>(l)]) continue;
      const Eigen::Vector3f x = landmark_in_camera(p, l);
      if (x.z() <= 1.0f) continue;
      errors[static_cast<std::size_t>(m++)] =
          (pixel_of(x) - landmarks->points[static_cast<std::size_t>(l)]).norm();
    }
    if (m < 10) return 1e9f;
    std::nth_element(errors.begin(), errors.begin() + m / 2, errors.begin() + m);
    return errors[static_cast<std::size_t>(m / 2)];
  };
  bool found = false;
  IcpStats best;
  Pose best_pose;
  for (int c = 0; c < count; ++c) {
    Pose p = candidates[c];
    IcpStats s = icp(smoothed, full, p, options.acquire_iterations, 40.0f, options.icp_gate_mm);
    if (!acceptable(s, true, from_landmarks)) continue;
    if (calibrated) {
      // The face may show any expression: fit the weights at this pose and refine it before
      // judging the residual (a neutral face on an open jaw leaves several mm).
      int unused = 0;
      solve_weights(smoothed, full, p, options.weight_iterations, true, landmarks, unused);
      s = icp(smoothed, full, p, options.icp_iterations, options.icp_gate_mm, options.icp_gate_mm);
    }
    if (!good(s) || (from_landmarks && landmark_error_px(p) > options.acquire_landmark_px)) {
      weights = previous_weights;
      update_current();
      continue;
    }
    found = true;
    best = s;
    best_pose = p;
    break;  // candidates are in order of evidence: the first good fit is the face
  }
  stats = best;
  if (found) pose = best_pose;
  return found;
}

float FaceTracker::State::calibrate() {
  // Identity and the calibration frames' poses by joint Gauss-Newton on the point-to-plane
  // residuals of all stored frames, r = n . (x - q) with x = R_f (neutral_i + U_i c) + t_f,
  // and a Tikhonov prior on c (coefficients are in sigma units). The unknowns are c (m) and a
  // twist per frame (6); the poses are eliminated by their Schur complement:
  //   (A + lambda I - sum_f B_f D_f^-1 B_f^T) dc = -(g_c + lambda c) + sum_f B_f D_f^-1 g_f,
  //   dp_f = -D_f^-1 (g_f + B_f^T dc),
  // A = sum w J_c J_c^T, B_f = sum w J_c J_p^T, D_f = sum w J_p J_p^T over frame f's rows.
  // Alternating the two blocks instead converged slowly along the directions where a change
  // of shape and a head rotation look alike, and stopped degrees short when the mean face
  // started a few degrees off (a held-out occluder take: 8.4 deg, its lids then untracked).
  // The projective association moves with every step, so the iterates end up circling the
  // minimum (|dc| ~ 0.4 sigma); the identity is their mean over the second half of the rounds.
  using PoseMatrix = Eigen::Matrix<double, 6, 6>;
  using PoseVector = Eigen::Matrix<double, 6, 1>;
  Eigen::MatrixXd a(modes, modes), schur(modes, modes), bd(modes, 6);
  Eigen::VectorXd gc(modes), rhs(modes), c_sum = Eigen::VectorXd::Zero(modes);
  std::vector<Eigen::MatrixXd> b_frames(static_cast<std::size_t>(calib_count),
                                        Eigen::MatrixXd(modes, 6));
  std::vector<PoseMatrix> d_frames(static_cast<std::size_t>(calib_count));
  std::vector<Eigen::LDLT<PoseMatrix>> d_solvers(static_cast<std::size_t>(calib_count));
  std::vector<PoseVector> g_frames(static_cast<std::size_t>(calib_count));
  Eigen::VectorXf row(modes);
  Eigen::VectorXd c = Eigen::VectorXd::Zero(modes);
  for (int j = 0; j < modes && j < static_cast<int>(identity.size()); ++j)
    c[j] = identity[static_cast<std::size_t>(j)];
  std::vector<float> coefficients(static_cast<std::size_t>(modes));
  auto rebuild = [&](bool keep_rigid) {
    for (int j = 0; j < modes; ++j)
      coefficients[static_cast<std::size_t>(j)] = static_cast<float>(c[j]);
    const Twist rigid = rigid_of_mode * c.cast<float>();
    build_rig(coefficients, keep_rigid ? Twist::Zero() : rigid);
    weights.setZero();  // the subject holds a neutral face while calibrating
    update_current();
  };
  int averaged = 0;
  for (int round = 0; round < options.calibration_rounds; ++round) {
    rebuild(false);
    a.setZero();
    gc.setZero();
    for (int f = 0; f < calib_count; ++f) {
      const auto fi = static_cast<std::size_t>(f);
      const Pose& p = calib_pose[fi];
      const Eigen::Vector3f pivot = p.r * centroid + p.t;
      Eigen::MatrixXd& b = b_frames[fi];
      PoseMatrix& d = d_frames[fi];
      PoseVector& gp = g_frames[fi];
      b.setZero();
      d.setZero();
      gp.setZero();
      // A residual r with identity row rd and pose row jp, weight w, into the normal equations.
      auto add_row = [&](const Eigen::VectorXd& rd, const PoseVector& jp, auto r, float w) {
        a.selfadjointView<Eigen::Lower>().rankUpdate(rd, w);
        gc += (w * r) * rd;
        b.noalias() += (w * rd) * jp.transpose();
        d.noalias() += w * jp * jp.transpose();
        gp += (w * r) * jp;
      };
      for (int i = 0; i < n; ++i) {
        Eigen::Vector3f x, nn, q;
        if (!facing_sample(p, i, x, nn)) continue;
        if (!measured_point(calib_depth[fi], calib_box[fi], x, q)) continue;
        const Eigen::Vector3f& nm = normals[static_cast<std::size_t>(i)];
        const float r = nn.dot(x - q);
        const float w = tukey(r, options.icp_gate_mm);
        if (w <= 0.0f) continue;
        // d r / d c = n_camera . R U_i = n_model . U_i; d r / d (omega, t) as in icp().
        row = nm.x() * identity_at_samples.row(3 * i) +
              nm.y() * identity_at_samples.row(3 * i + 1) +
              nm.z() * identity_at_samples.row(3 * i + 2);
        PoseVector jp;
        jp.head<3>() = (x - pivot).cross(nn).cast<double>();
        jp.tail<3>() = nn.cast<double>();
        add_row(row.cast<double>(), jp, r, w);
      }
      // Landmark rows: the reprojection error r = proj(R m_l(c) + t) - detected of each interior
      // landmark, per image axis a with v_a the row of d proj / d x (model frame): d r_a / d c =
      // v_a . dm_l/dc, where dm_l/dc is the mode minus its rigid part (rebuild(false)),
      // omega x (mean_l - pivot) + t; d r_a / d (omega, t) = ((x - pivot) x v_a, v_a) (camera).
      // Depth sees a lip or a lid slide along the face hardly at all; the landmarks do.
      const float lw = options.calibration_landmark_weight * calib_landmark_scale[fi];
      for (int l = 17; l < 68 && lw > 0.0f; ++l) {
        const std::size_t at = fi * 68 + static_cast<std::size_t>(l);
        if (!calib_landmark_valid[at]) continue;
        const Eigen::Vector3f x = landmark_in_camera(p, l);
        if (x.z() <= 1.0f) continue;
        const Eigen::Vector2f res = pixel_of(x) - calib_landmarks[at];
        const float rn = res.norm();
        const float w =
            lw * (rn < options.landmark_huber_px ? 1.0f : options.landmark_huber_px / rn);
        const Eigen::Matrix<float, 2, 3> jproj = projection_jacobian(x);
        const Eigen::Matrix<float, 2, 3> jmodel = jproj * p.r;
        const auto mv = model->landmark_vertices[static_cast<std::size_t>(l)];
        const Eigen::Vector3f y =
            Eigen::Vector3f(model->neutral[3 * mv], model->neutral[3 * mv + 1],
                            model->neutral[3 * mv + 2]) -
            rigid_pivot;
        for (int ax = 0; ax < 2; ++ax) {
          const Eigen::Vector3f vm = jmodel.row(ax).transpose();
          row = vm.x() * identity_at_landmarks.row(3 * l) +
                vm.y() * identity_at_landmarks.row(3 * l + 1) +
                vm.z() * identity_at_landmarks.row(3 * l + 2);
          row.noalias() -= rigid_of_mode.topRows<3>().transpose() * y.cross(vm);
          row.noalias() -= rigid_of_mode.bottomRows<3>().transpose() * vm;
          const Eigen::Vector3f vc = jproj.row(ax).transpose();
          PoseVector jp;
          jp.head<3>() = (x - pivot).cross(vc).cast<double>();
          jp.tail<3>() = vc.cast<double>();
          add_row(row.cast<double>(), jp, static_cast<double>(res[ax]), w);
        }
      }
    }
    schur = a.selfadjointView<Eigen::Lower>();
    schur.diagonal().array() += options.identity_prior;
    rhs = -(gc + options.identity_prior * c);
    for (int f = 0; f < calib_count; ++f) {
      const auto fi = static_cast<std::size_t>(f);
      d_frames[fi].diagonal().array() += 1e-3;
      d_solvers[fi].compute(d_frames[fi]);
      bd = d_solvers[fi].solve(b_frames[fi].transpose()).transpose();  // B_f D_f^-1
      schur.noalias() -= bd * b_frames[fi].transpose();
      rhs.noalias() += bd * g_frames[fi];
    }
    const Eigen::VectorXd dc = schur.ldlt().solve(rhs);
    c += dc;
    for (int f = 0; f < calib_count; ++f) {
      const auto fi = static_cast<std::size_t>(f);
      const PoseVector xi = d_solvers[fi].solve(-(g_frames[fi] + b_frames[fi].transpose() * dc));
      Pose& p = calib_pose[fi];
      p.apply_twist(xi.head<3>().cast<float>(), xi.tail<3>().cast<float>(), p.r * centroid + p.t);
      p.r = Eigen::Quaternionf(p.r).normalized().toRotationMatrix();
    }
    if (2 * round >= options.calibration_rounds) {
      c_sum += c;
      ++averaged;
    }
  }
  if (averaged > 0) c = c_sum / averaged;
  // The final face keeps the identity's rigid part when asked (keep_identity_rigid): the PCA
  // modes tie it to their shape, so the fitted shape predicts it, and the face's frame then
  // stays the model's (absolute pose) instead of moving by the removed motion. The stored
  // frames are re-tracked with it.
  rebuild(options.keep_identity_rigid);
  build_subject_blendshapes();
  float rms_sum = 0.0f;
  for (int f = 0; f < calib_count; ++f) {
    rms_sum += icp(calib_depth[static_cast<std::size_t>(f)], calib_box[static_cast<std::size_t>(f)],
                   calib_pose[static_cast<std::size_t>(f)], options.icp_iterations,
                   options.icp_gate_mm, options.icp_gate_mm)
                   .rms;
  }
  if (options.calibrate_depth_offsets) calibrate_depth_offsets();
  if (options.calibrate_landmark_offsets) calibrate_landmark_offsets();
  // Continue from the last calibration frame.
  pose = calib_pose[static_cast<std::size_t>(calib_count - 1)];
  weights.setZero();
  previous_weights = weights;
  update_current();
  calibrated = true;
  return rms_sum / static_cast<float>(calib_count);
}

void FaceTracker::State::calibrate_landmark_offsets() {
  // Mean over the calibration frames (neutral face, final poses) of the detected point's ray at
  // the model landmark's depth minus the model landmark, rotated into the model frame:
  //   d_l = mean_f R_f^T ([(u - cx) z / fx, (v - cy) z / fy, z] - x),  x = R_f m_l + t_f.
  // The identity fit sees depth only, so a detector's consistent placement on this face (and
  // the identity's error at the landmark vertices) would otherwise pull the expression weights
  // on every frame. Points seen on fewer than half the frames, or further off than
  // max_landmark_offset_mm, keep no offset.
  landmark_base -= landmark_offset;  // the model's landmark vertices on this face
  landmark_offset.setZero();
  weights.setZero();
  update_current();
  for (int l = 17; l < 68; ++l) {
    Eigen::Vector3f sum = Eigen::Vector3f::Zero();
    int seen = 0;
    for (int f = 0; f < calib_count; ++f) {
      const std::size_t at = static_cast<std::size_t>(f) * 68 + static_cast<std::size_t>(l);
      if (!calib_landmark_valid[at]) continue;
      const Pose& p = calib_pose[static_cast<std::size_t>(f)];
      const Eigen::Vector3f x = landmark_in_camera(p, l);
      if (x.z() <= 1.0f) continue;
      const Eigen::Vector2f& px = calib_landmarks[at];
      // On the measured surface where the frame has depth there: the model's depth alone leaves
      // the offset's component along the view, which shows once the head turns.
      float z = x.z(), measured = 0.0f;
      if (options.landmark_offset_depth_gate_mm > 0.0f &&
          depth_at(calib_depth[static_cast<std::size_t>(f)], calib_box[static_cast<std::size_t>(f)],
                   px.x(), px.y(), measured) &&
          std::abs(measured - x.z()) <= options.landmark_offset_depth_gate_mm)
        z = measured;
      const Eigen::Vector3f ray((px.x() - cx) * z / fx, (px.y() - cy) * z / fy, z);
      sum += p.r.transpose() * (ray - x);
      ++seen;
    }
    if (2 * seen < calib_count || seen == 0) continue;
    const Eigen::Vector3f d = sum / static_cast<float>(seen);
    if (d.norm() <= options.max_landmark_offset_mm) landmark_offset.segment<3>(3 * l) = d;
  }
  landmark_base += landmark_offset;
  update_current();
}

void FaceTracker::State::calibrate_depth_offsets() {
  // o_i = mean_f n_i . (q_f - x_f) over the frames where sample i has an inlier depth (model
  // frame, neutral face, final calibration poses); base_i += o_i n_i. Per sample: what the
  // identity fit misses that moved the weights was fine-scale (take 1002: averaging the offsets
  // over 8 mm lost it, and the browDown_R stand-in came back).
  weights.setZero();
  update_current();
  std::fill(found_residual.begin(), found_residual.end(), 0.0f);  // sum of residuals
  std::fill(found_sample.begin(), found_sample.end(), 0);         // frames seen
  for (int f = 0; f < calib_count; ++f) {
    const auto fi = static_cast<std::size_t>(f);
    const Pose& p = calib_pose[fi];
    const Eigen::Matrix3f rt = p.r.transpose();
    for (int i = 0; i < n; ++i) {
      Eigen::Vector3f x, nn, measured;
      if (!facing_sample(p, i, x, nn)) continue;
      if (!measured_point(calib_depth[fi], calib_box[fi], x, measured)) continue;
      const Eigen::Vector3f q = rt * (measured - p.t);
      const float r = normals[static_cast<std::size_t>(i)].dot(q - sample(i));
      if (std::abs(r) > options.icp_gate_mm) continue;
      found_residual[static_cast<std::size_t>(i)] += r;
      ++found_sample[static_cast<std::size_t>(i)];
    }
  }
  for (int i = 0; i < n; ++i) {
    const auto ii = static_cast<std::size_t>(i);
    if (found_sample[ii] == 0 || 2 * found_sample[ii] < calib_count) continue;
    const float o = std::clamp(found_residual[ii] / static_cast<float>(found_sample[ii]),
                               -options.max_depth_offset_mm, options.max_depth_offset_mm);
    base.segment<3>(3 * i) += o * normals[ii];
  }
  update_current();
}

void FaceTracker::State::output(TrackReport& report, double time_s) {
  const double dt = have_time ? time_s - last_time : 0.0;
  filtered = filter.update(pose.to_rigid(), dt);
  last_time = time_s;
  have_time = true;
  report.camera_from_model = filtered;
  report.raw_camera_from_model = pose.to_rigid();
  report.shape_count = k;
  std::fill(report.weights.begin(), report.weights.end(), 0.0f);
  for (int j = 0; j < k; ++j) report.weights[static_cast<std::size_t>(j)] = weights[j];
  std::fill(report.weight_sigma.begin(), report.weight_sigma.end(), 0.0f);
  if (options.report_weight_sigma)
    for (int j = 0; j < k; ++j) report.weight_sigma[static_cast<std::size_t>(j)] = weight_sigma[j];
}

void FaceTracker::State::estimate_weight_sigma(int depth_rows, int landmark_rows,
                                               float depth_sigma_mm) {
  // Fisher information: the depth rows over the MAD noise of this frame's residuals; the
  // landmark rows carry sqrt(landmark_weight * landmark_scale) and a source's points have
  // noise_px = landmark_noise_px / sqrt(landmark_scale), so their row noise is
  // sqrt(landmark_weight) * landmark_noise_px whatever the source. Robust weights stay in the
  // rows: a down-weighted sample informs less. `h` holds the Gram matrix of all the rows
  // (depth and landmarks, before the priors), so only the landmark rows' is built again.
  const float depth_variance = depth_sigma_mm * depth_sigma_mm;
  information = h / depth_variance;
  if (landmark_rows > 0) {
    set_gram(rows, depth_rows, landmark_rows, landmark_gram);
    information +=
        landmark_gram *
        (1.0f / (options.landmark_weight * options.landmark_noise_px * options.landmark_noise_px) -
         1.0f / depth_variance);
  }
  weight_standard_errors(information, 1e-3f * signal_median / depth_variance, weight_sigma);
}

FaceTracker::FaceTracker(std::unique_ptr<State> state) : state_(std::move(state)) {}
FaceTracker::~FaceTracker() = default;

Result<std::unique_ptr<FaceTracker>> FaceTracker::create(const FaceModel& model,
                                                         const PinholeIntrinsics& intrinsics,
                                                         const TrackerOptions& options) {
  if (model.vertex_count <= 0 || model.fitting_expression_count <= 0 ||
      model.neutral.size() != static_cast<std::size_t>(3 * model.vertex_count)) {
    return fail("tracking: the face model is empty; load data/facemodel.fbfm first");
  }
  if (model.fitting_expression_count > kMaxTrackedShapes) {
    return fail("tracking: the model has " + std::to_string(model.fitting_expression_count) +
                " fitting shapes; at most " + std::to_string(kMaxTrackedShapes) + " are supported");
  }
  if (intrinsics.fx <= 0.0 || intrinsics.fy <= 0.0 || intrinsics.width <= 0 ||
      intrinsics.height <= 0) {
    return fail("tracking: the camera reports no depth intrinsics");
  }
  if (options.temporal_frames < 1 || options.temporal_frames > 16) {
    return fail("tracking: temporal_frames must be in [1, 16]");
  }
  if (options.calibration_frames < 1) return fail("tracking: calibration_frames must be >= 1");
  if (!(options.landmark_noise_px > 0.0f)) return fail("tracking: landmark_noise_px must be > 0");
  auto s = std::make_unique<State>();
  s->model = &model;
  s->options = options;
  s->intrinsics = intrinsics;
  s->fx = static_cast<float>(intrinsics.fx), s->fy = static_cast<float>(intrinsics.fy);
  s->cx = static_cast<float>(intrinsics.cx), s->cy = static_cast<float>(intrinsics.cy);
  s->width = intrinsics.width, s->height = intrinsics.height;
  s->k = model.fitting_expression_count;
  s->modes = std::clamp(options.identity_modes, 0, model.identity_count);
  s->filter = PoseFilter(options.pose_filter);
  s->gaze_shape.resize(static_cast<std::size_t>(s->k));
  for (int j = 0; j < s->k; ++j)
    s->gaze_shape[static_cast<std::size_t>(j)] =
        static_cast<std::size_t>(j) < model.expression_names.size() &&
                is_gaze_shape(model.expression_names[static_cast<std::size_t>(j)])
            ? 1
            : 0;

  // Antagonist pairs (TrackerOptions::antagonist_weight), per side.
  for (const char* side : {"_L", "_R"}) {
    constexpr std::pair<std::string_view, std::string_view> kPairs[] = {{"browDown", "browInnerUp"},
                                                                        {"browDown", "browOuterUp"},
                                                                        {"eyeWide", "eyeBlink"},
                                                                        {"eyeWide", "eyeSquint"}};
    for (const auto& [first, second] : kPairs) {
      const int a = model.expression_index(std::string(first) + side);
      const int b = model.expression_index(std::string(second) + side);
      if (a >= 0 && b >= 0 && a < s->k && b < s->k) s->antagonists.emplace_back(a, b);
    }
  }

  // --- Sample selection on the mean face: front-facing fitting vertices, one per grid cell,
  // plus the most-displaced vertices of every shape so small shapes (blinks, brows) are seen.
  const int v_count = model.vertex_count;
  std::vector<float> neutral = model.neutral;
  std::vector<Eigen::Vector3f> vn(static_cast<std::size_t>(v_count), Eigen::Vector3f::Zero());
  auto nv = [&](std::uint32_t v) {
    return Eigen::Vector3f(neutral[3 * v], neutral[3 * v + 1], neutral[3 * v + 2]);
  };
  for (std::size_t t = 0; t + 2 < model.triangles.size(); t += 3) {
    const auto a = model.triangles[t], b = model.triangles[t + 1], c = model.triangles[t + 2];
    const Eigen::Vector3f nn = (nv(b) - nv(a)).cross(nv(c) - nv(a));
    vn[a] += nn, vn[b] += nn, vn[c] += nn;
  }
  // Boundary vertices (edges of one triangle): the eye and mouth openings. Depth there sees
  // eyeballs, teeth or the mouth cavity, which the skin model does not have, so vertices within
  // `hole_margin` of them are not sampled.
  std::vector<char> boundary(static_cast<std::size_t>(v_count), 0);
  {
    std::unordered_map<long long, int> edges;
    auto key = [](std::uint32_t a, std::uint32_t b) {
      return static_cast<long long>(std::min(a, b)) * 1000003LL + std::max(a, b);
    };
    for (std::size_t t = 0; t + 2 < model.triangles.size(); t += 3) {
      for (int e = 0; e < 3; ++e)
        ++edges[key(model.triangles[t + e], model.triangles[t + (e + 1) % 3])];
    }
    for (const auto& [k, count] : edges) {
      if (count == 1) {
        boundary[static_cast<std::size_t>(k / 1000003LL)] = 1;
        boundary[static_cast<std::size_t>(k % 1000003LL)] = 1;
      }
    }
  }
  std::vector<Eigen::Vector3f> hole_points;
  for (int v = 0; v < model.face_vertex_count; ++v) {
    if (boundary[static_cast<std::size_t>(v)])
      hole_points.push_back(nv(static_cast<std::uint32_t>(v)));
  }
  std::vector<std::uint32_t> candidates;
  for (auto v : model.fitting_vertices) {
    if (static_cast<int>(v) >= model.face_vertex_count) continue;
    if (vn[v].normalized().z() < 0.25f) continue;
    bool near_hole = false;
    for (const auto& h : hole_points) {
      if ((h - nv(v)).squaredNorm() < options.hole_margin_mm * options.hole_margin_mm) {
        near_hole = true;
        break;
      }
    }
    if (!near_hole) candidates.push_back(v);
  }
  if (candidates.size() < 200) return fail("tracking: the face model has too few face vertices");
  std::unordered_map<long long, std::uint32_t> cells;
  std::vector<char> chosen(static_cast<std::size_t>(v_count), 0);
  const float spacing = std::max(1.0f, options.sample_spacing_mm);
  for (auto v : candidates) {
    const Eigen::Vector3f p = nv(v);
    const long long key = (static_cast<long long>(std::floor(p.x() / spacing)) + 100000) * 200001 +
                          static_cast<long long>(std::floor(p.y() / spacing)) + 100000;
    if (cells.emplace(key, v).second) chosen[v] = 1;
  }
  for (int j = 0; j < s->k; ++j) {
    const auto shape = model.expression_shape(j);
    std::vector<std::pair<float, std::uint32_t>> moved;
    for (auto v : candidates) {
      const float d = Eigen::Vector3f(shape[3 * v], shape[3 * v + 1], shape[3 * v + 2]).norm();
      if (d > 0.5f) moved.emplace_back(d, v);
    }
    const std::size_t take = std::min<std::size_t>(
        moved.size(), static_cast<std::size_t>(options.extra_samples_per_shape));
    std::partial_sort(moved.begin(), moved.begin() + take, moved.end(),
                      [](const auto& a, const auto& b) { return a.first > b.first; });
    for (std::size_t i = 0; i < take; ++i) chosen[moved[i].second] = 1;
  }
  for (int v = 0; v < v_count; ++v) {
    if (chosen[static_cast<std::size_t>(v)])
      s->sample_vertices.push_back(static_cast<std::uint32_t>(v));
  }
  const int n = static_cast<int>(s->sample_vertices.size());
  s->n = n;

  // --- Identity-independent bases at the samples and landmarks.
  s->expression_at_samples.resize(3 * n, s->k);
  s->identity_at_samples.resize(3 * n, s->modes);
  s->expression_at_landmarks.resize(3 * 68, s->k);
  s->identity_at_landmarks.resize(3 * 68, s->modes);
  auto fill = [&](auto& out, std::span<const std::uint32_t> vertices, bool expression) {
    const int columns = expression ? s->k : s->modes;
    for (int j = 0; j < columns; ++j) {
      const auto shape = expression ? model.expression_shape(j) : model.identity_mode(j);
      for (std::size_t i = 0; i < vertices.size(); ++i) {
        for (int a = 0; a < 3; ++a)
          out(3 * static_cast<int>(i) + a, j) = shape[3 * vertices[i] + a];
      }
    }
  };
  fill(s->expression_at_samples, s->sample_vertices, true);
  fill(s->identity_at_samples, s->sample_vertices, false);
  fill(s->expression_at_landmarks, model.landmark_vertices, true);
  fill(s->identity_at_landmarks, model.landmark_vertices, false);
  s->model_expression_at_samples = s->expression_at_samples;
  s->model_expression_at_landmarks = s->expression_at_landmarks;
  {
    // Rigid part of every identity mode at the samples: least squares against the 6 rigid
    // motions of the mean face about its sample centroid, then removed from the basis.
    Eigen::Vector3f pivot = Eigen::Vector3f::Zero();
    for (auto v : s->sample_vertices) pivot += nv(v);
    pivot /= static_cast<float>(n);
    s->rigid_pivot = pivot;
    Eigen::MatrixXd g(3 * n, 6);
    for (int i = 0; i < n; ++i) {
      const Eigen::Vector3d x =
          (nv(s->sample_vertices[static_cast<std::size_t>(i)]) - pivot).cast<double>();
      for (int a = 0; a < 3; ++a) {
        const Eigen::Vector3d e = Eigen::Vector3d::Unit(a);
        g.block<3, 1>(3 * i, a) = e.cross(x);  // rotation about axis a
        g.block<3, 1>(3 * i, 3 + a) = e;       // translation along a
      }
    }
    const Eigen::MatrixXd alpha =
        (g.transpose() * g).ldlt().solve(g.transpose() * s->identity_at_samples.cast<double>());
    s->rigid_of_mode = alpha.cast<float>();
    s->identity_at_samples -= (g * alpha).cast<float>();
  }

  // --- Buffers at their final size.
  s->weights = ShapeVector::Zero(s->k);
  s->previous_weights = ShapeVector::Zero(s->k);
  s->h.resize(s->k, s->k);
  s->h_hidden.resize(s->k, s->k);
  s->information.resize(s->k, s->k);
  s->landmark_gram.resize(s->k, s->k);
  s->weight_sigma = ShapeVector::Zero(s->k);
  s->g.resize(s->k);
  s->rows.resize(n + 2 * 68, s->k);
  s->targets.resize(n + 2 * 68);
  s->found_sample.resize(static_cast<std::size_t>(n));
  s->found_residual.resize(static_cast<std::size_t>(n));
  s->found_target.resize(static_cast<std::size_t>(n));
  s->abs_scratch.resize(static_cast<std::size_t>(n));
  s->occluded.assign(static_cast<std::size_t>(n), 0);
  s->current.resize(3 * n);
  s->landmark_current.resize(3 * 68);
  s->ring.resize(static_cast<std::size_t>(options.temporal_frames));
  for (auto& f : s->ring) f.resize(s->width, s->height);
  s->smoothed.resize(s->width, s->height);
  s->spatial_scratch.resize(s->width, s->height);
  s->calib_depth.resize(static_cast<std::size_t>(options.calibration_frames));
  for (auto& f : s->calib_depth) f.resize(s->width, s->height);
  s->calib_box.resize(static_cast<std::size_t>(options.calibration_frames));
  s->calib_landmarks.assign(static_cast<std::size_t>(options.calibration_frames) * 68,
                            Eigen::Vector2f::Zero());
  s->calib_landmark_valid.assign(static_cast<std::size_t>(options.calibration_frames) * 68, 0);
  s->calib_landmark_scale.assign(static_cast<std::size_t>(options.calibration_frames), 1.0f);
  s->landmark_offset = Eigen::VectorXf::Zero(3 * 68);
  s->calib_pose.resize(static_cast<std::size_t>(options.calibration_frames));
  s->calib_weights.assign(static_cast<std::size_t>(options.calibration_frames),
                          ShapeVector::Zero(s->k));
  s->build_rig({});
  return std::unique_ptr<FaceTracker>(new FaceTracker(std::move(s)));
}

Result<void> FaceTracker::set_identity(std::span<const float> coefficients) {
  State& s = *state_;
  if (coefficients.size() > static_cast<std::size_t>(s.model->identity_count)) {
    return fail("tracking: " + std::to_string(coefficients.size()) +
                " identity coefficients given, the model has " +
                std::to_string(s.model->identity_count));
  }
  s.use_model_expressions();
  s.landmark_offset.setZero();  // measured by calibration only
  s.build_rig(coefficients);
  s.build_subject_blendshapes();
  s.calibrated = true;
  s.calib_count = 0;
  return success();
}

Result<void> FaceTracker::set_rig(const TrackerRig& rig) {
  State& s = *state_;
  const FaceModel& m = *s.model;
  const std::size_t size = static_cast<std::size_t>(3 * m.vertex_count);
  if (rig.neutral.size() != size) {
    return fail("tracking: the rig's neutral has " + std::to_string(rig.neutral.size() / 3) +
                " vertices, the face model " + std::to_string(m.vertex_count) +
                "; only rigs in the face model's topology can be tracked");
  }
  for (const auto& [index, shape] : rig.shapes) {
    if (index < 0 || index >= s.k) {
      return fail("tracking: rig shape index " + std::to_string(index) +
                  " is not one of the model's " + std::to_string(s.k) + " fitting shapes");
    }
    if (shape.size() != size) {
      return fail("tracking: rig shape '" + m.expression_names[static_cast<std::size_t>(index)] +
                  "' does not have the neutral's vertex count");
    }
  }
  s.expression_at_samples = s.model_expression_at_samples;
  s.expression_at_landmarks = s.model_expression_at_landmarks;
  auto replace = [&](auto& out, std::span<const std::uint32_t> vertices, int j,
                     std::span<const float> shape) {
    for (std::size_t i = 0; i < vertices.size(); ++i) {
      for (int a = 0; a < 3; ++a) {
        const std::size_t c = 3 * vertices[i] + static_cast<std::size_t>(a);
        out(3 * static_cast<int>(i) + a, j) = shape[c] - rig.neutral[c];
      }
    }
  };
  for (const auto& [index, shape] : rig.shapes) {
    replace(s.expression_at_samples, s.sample_vertices, index, shape);
    replace(s.expression_at_landmarks, m.landmark_vertices, index, shape);
  }
  s.custom_rig = true;
  s.identity.assign(static_cast<std::size_t>(s.modes), 0.0f);
  s.mesh_scratch.assign(rig.neutral.begin(), rig.neutral.end());
  s.landmark_offset.setZero();
  s.finish_rig();
  s.calibrated = true;
  s.calib_count = 0;
  return success();
}

void FaceTracker::set_subject_blendshapes(const SubjectBlendshapes* source) {
  state_->subject_blendshapes = source;
}

void FaceTracker::reset() {
  State& s = *state_;
  s.calibrated = false;
  s.calib_count = 0;
  s.have_pose = s.have_last_good = s.lost = s.have_time = false;
  s.ring_count = 0;
  s.weights.setZero();
  s.previous_weights.setZero();
  s.filter.reset();
  s.occlusion.reset();
  s.landmark_offset.setZero();
  s.use_model_expressions();
  s.build_rig({});
}

bool FaceTracker::calibrated() const {
  return state_->calibrated;
}
std::span<const float> FaceTracker::identity() const {
  return state_->identity;
}
int FaceTracker::sample_count() const {
  return state_->n;
}
int FaceTracker::shape_count() const {
  return state_->k;
}
std::span<const int> FaceTracker::weak_shapes() const {
  return state_->weak_shapes;
}
std::span<const std::string> FaceTracker::shape_names() const {
  return std::span<const std::string>(state_->model->expression_names)
      .first(static_cast<std::size_t>(state_->k));
}

void FaceTracker::track(const DepthImage& depth, double time_s, const TrackLandmarks* landmarks,
                        TrackReport& report) {
  State& s = *state_;
  report.times = {};
  report.face_found = false;
  report.loss_reason = "";
  report.samples_used = report.inliers = report.landmarks_used = 0;
  report.rms_mm = 0.0f;
  report.calibration_frames_left = s.calibrated ? 0 : s.options.calibration_frames - s.calib_count;
  report.occluded_fraction = s.occlusion.fraction();  // held unless this frame measures
  report.occluded = s.occlusion.occluded();
  auto keep_last = [&](TrackState state, const char* reason) {
    report.state = state;
    report.loss_reason = reason;
    report.camera_from_model = s.filtered;
    report.raw_camera_from_model = s.pose.to_rigid();
    report.shape_count = s.k;
    for (int j = 0; j < s.k; ++j)
      report.weights[static_cast<std::size_t>(j)] = s.previous_weights[j];
  };
  if (depth.width != s.width || depth.height != s.height ||
      depth.pixels.size() != static_cast<std::size_t>(s.width) * s.height) {
    keep_last(TrackState::kBadInput, "depth frame size does not match the camera intrinsics");
    return;
  }
  auto start = Clock::now();

  // Ring buffer: the newest frame goes into the next slot (a copy, so callers reuse theirs).
  s.ring_head = (s.ring_head + 1) % static_cast<int>(s.ring.size());
  std::copy(depth.pixels.begin(), depth.pixels.end(),
            s.ring[static_cast<std::size_t>(s.ring_head)].pixels.begin());
  s.ring_count = std::min(s.ring_count + 1, static_cast<int>(s.ring.size()));

  s.mask_on = false;  // acquisition and calibration start from poses no mask was made for
  const bool searching = !s.have_pose || s.lost;
  s.box = searching ? Box{0, 0, s.width, s.height} : s.predicted_box(s.pose);
  const int valid = s.smooth(depth, s.box);
  s.smooth_spatially(s.box);
  report.times.smooth_ms = ms_since(start);
  if (valid < 50) {
    s.lost = s.have_pose;
    keep_last(searching ? TrackState::kBadInput : TrackState::kLost,
              searching ? "no valid depth in the frame" : "no valid depth where the face was");
    return;
  }

  State::IcpStats stats;
  bool recovered = false;
  if (searching) {
    start = Clock::now();
    const bool found = s.acquire(landmarks, stats);
    report.times.acquire_ms = ms_since(start);
    if (!found) {
      keep_last(s.have_pose ? TrackState::kLost : TrackState::kSearching, "no face found");
      if (s.have_pose) report.state = TrackState::kSearching;
      return;
    }
    recovered = s.have_pose;
    s.have_pose = true;
    s.lost = false;
    s.box = s.predicted_box(s.pose);
    s.smooth(depth, s.box);
    s.smooth_spatially(s.box);
  }

  start = Clock::now();
  s.mark_occluded(s.smoothed, s.box, s.pose, landmarks);
  stats = s.icp(s.smoothed, s.box, s.pose, s.options.icp_iterations, s.options.icp_first_gate_mm,
                s.options.icp_gate_mm);
  report.times.icp_ms = ms_since(start);
  report.samples_used = stats.used;
  report.inliers = stats.inliers;
  report.rms_mm = stats.rms;
  // Measured before the loss test: a hand that covers enough of the face to lose it is
  // reported on that frame, and held while the face is searched for.
  s.occlusion.measure(s.mask_on ? hidden_fraction(stats.hidden, stats.facing) : 0.0f,
                      s.options.occlusion_report_fraction);
  report.occluded_fraction = s.occlusion.fraction();
  report.occluded = s.occlusion.occluded();
  const bool face_seen = landmarks != nullptr && landmarks->points.size() >= 68;
  if (!s.acceptable(stats, false, face_seen)) {
    s.lost = true;
    s.pose = s.last_good_pose;
    keep_last(TrackState::kLost, stats.inliers < s.options.min_inliers ? "too few depth inliers"
                                 : stats.rms > s.max_rms_mm(face_seen) ? "residual too large"
                                                                       : "too few inliers");
    return;
  }

  start = Clock::now();
  // While calibrating the face is assumed neutral: expression weights would absorb the
  // identity difference the calibration is about to measure.
  // The mask of the ICP's start pose serves the weights too (ICP moves the face by a few mm,
  // far below the mask's margin).
  double refine_ms = 0.0;  // counted as ICP in the stage split, not as weights
  if (s.calibrated) {
    // ICP fitted the face with the last frame's weights. Where a shape moves little depth (a
    // brow against a pitch of the forehead), the pose takes part of this frame's expression
    // change and the weight solve the rest of the pose error; a few ICP iterations against the
    // face with this frame's first weights, then the remaining IRLS rounds, split them again.
    // The iterations are those of the weight solve split around them, so this costs only the
    // ICP iterations.
    const int iterations = s.options.weight_iterations;
    const bool refine = s.options.pose_refine_iterations > 0 && iterations > 1;
    s.solve_weights(s.smoothed, s.box, s.pose, refine ? 1 : iterations, !refine, landmarks,
                    report.landmarks_used);
    if (refine) {
      const auto refine_start = Clock::now();
      s.icp(s.smoothed, s.box, s.pose, s.options.pose_refine_iterations, s.options.icp_gate_mm,
            s.options.icp_gate_mm);
      refine_ms = ms_since(refine_start);
      s.solve_weights(s.smoothed, s.box, s.pose, iterations - 1, true, landmarks,
                      report.landmarks_used);
    }
  }
  s.mask_on = false;  // calibrate() below re-tracks stored frames: not this frame's mask
  report.times.icp_ms += refine_ms;
  report.times.weights_ms = ms_since(start) - refine_ms;
  s.previous_weights = s.weights;
  s.last_good_pose = s.pose;
  s.have_last_good = true;
  report.face_found = true;

  // A frame with the face occluded is no calibration frame: the identity would be fitted to
  // the face with a hand in front of it (its samples are masked, but so much of the face is
  // missing that hair and noise pull the fit).
  if (!s.calibrated && !report.occluded) {
    const auto f = static_cast<std::size_t>(s.calib_count);
    std::copy(s.smoothed.pixels.begin(), s.smoothed.pixels.end(), s.calib_depth[f].pixels.begin());
    s.calib_box[f] = s.box;
    s.calib_pose[f] = s.pose;
    s.calib_weights[f] = s.weights;
    const bool have_landmarks = landmarks != nullptr && landmarks->points.size() >= 68;
    s.calib_landmark_scale[f] = have_landmarks ? s.landmark_scale(*landmarks) : 1.0f;
    for (std::size_t l = 0; l < 68; ++l) {
      const bool valid = have_landmarks && (landmarks->valid.empty() || landmarks->valid[l] != 0);
      s.calib_landmark_valid[f * 68 + l] = valid ? 1 : 0;
      if (valid) s.calib_landmarks[f * 68 + l] = landmarks->points[l];
    }
    ++s.calib_count;
    report.calibration_frames_left = s.options.calibration_frames - s.calib_count;
    if (s.calib_count >= s.options.calibration_frames) {
      start = Clock::now();
      const float fit_rms = s.calibrate();
      report.times.calibrate_ms = ms_since(start);
      s.filter.reset();
      // The fitted face must explain its own calibration frames as well as a re-acquisition
      // would have to (acquire_max_rms_mm); when it does not, the frames were not one neutral
      // face at a right pose (a lock on the wrong pose, the subject moving or talking), and the
      // tracker starts over rather than track with a wrong face.
      if (fit_rms > s.options.acquire_max_rms_mm) {
        reset();
        report.face_found = false;
        keep_last(TrackState::kSearching,
                  "calibration did not fit this face: face the camera with a neutral face and "
                  "hold still");
        return;
      }
    }
  }
  s.output(report, time_s);
  report.state = !s.calibrated ? TrackState::kCalibrating
                 : recovered   ? TrackState::kRecovered
                               : TrackState::kTracking;
}

}  // namespace fb
