// FaceTracker's state and the helpers its stages share. Internal to algo/tracking: the stages
// live in one file each (face_tracker.cpp: set-up, the rig and the per-frame loop;
// tracker_depth.cpp: depth smoothing; tracker_solve.cpp: occlusion mask, ICP and the weight
// solve; tracker_acquire.cpp: finding the face; tracker_calibration.cpp: the identity fit).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <span>
#include <utility>
#include <vector>

#include "algo/tracking/depth_filter.hpp"
#include "algo/tracking/face_tracker.hpp"

namespace fb::tracker_detail {

using Clock = std::chrono::steady_clock;
using RowMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using ColMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::ColMajor>;

inline double ms_since(Clock::time_point start) {
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

inline const Eigen::Matrix3f kFlip = Eigen::Vector3f(1.0f, -1.0f, -1.0f).asDiagonal();

// gram = A^T A for A = rows [first, first + count), in chunks of rows: Eigen's GEMM packs its
// operands into a workspace that it heap-allocates above 128 KB (EIGEN_STACK_ALLOCATION_LIMIT);
// 256 x 53 floats stay on the stack, so the steady state does not allocate (and it is no
// slower). A symmetric rank-k update (SYRK) builds the lower triangle only, half the
// multiply-adds of the full product; the upper triangle is then mirrored (the solver reads
// whole columns).
inline void set_gram(const RowMatrix& rows, int first, int count, ShapeMatrix& gram) {
  constexpr int kChunkRows = 256;
  gram.setZero();
  for (int start = first; start < first + count; start += kChunkRows) {
    const int n = std::min(kChunkRows, first + count - start);
    gram.selfadjointView<Eigen::Lower>().rankUpdate(rows.middleRows(start, n).transpose());
  }
  gram = gram.selfadjointView<Eigen::Lower>();
}

}  // namespace fb::tracker_detail

namespace fb {

struct FaceTracker::State {
  using Pose = tracker_detail::Pose;
  using Box = tracker_detail::Box;
  using RowMatrix = tracker_detail::RowMatrix;
  using ColMatrix = tracker_detail::ColMatrix;

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
  ShapeMatrix h;
  ShapeVector g;
  ShapeMatrix h_hidden;  // imputed rows of the hidden samples, see solve_weights()

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
};

// Inline here: ICP and the weight solve call it for every sample (tracker_solve.cpp).
inline bool FaceTracker::State::depth_at(const Image<float>& image, const Box& b, float u, float v,
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

}  // namespace fb
