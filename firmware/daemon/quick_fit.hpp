// The device's processing after fusion (issue 8, FaceWarehouse 3.2): landmarks on the frontal
// colour frame (dlib, algo/landmarks), lifted into the fused depth, then the quick fit: the
// neutral fit for the first capture of a session (G0), the expression fit from that neutral
// (the model's expression shapes added, scaled to the capture, refined) for the others
// (algo/fitting). Corrections of landmark positions by the operator
// re-lift the points and refit.
//
// Owns the face model and the landmark detector, both loaded once (the shape predictor is the
// daemon's largest allocation, ~100 MB). Not thread-safe: the daemon uses it from its fit thread
// only; model() may be read from any thread (it never changes after create()).
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "algo/core/image.hpp"
#include "algo/core/result.hpp"
#include "algo/facemodel/face_model.hpp"
#include "algo/fitting/face_fit.hpp"
#include "algo/landmarks/landmark_detector.hpp"
#include "algo/sensor/kinect_calibration.hpp"
#include "firmware/daemon/guide_steps.hpp"
#include "firmware/daemon/http_requests.hpp"  // ColorCorrection
#include "storage/stored_data.hpp"

namespace fb {

struct QuickFitPaths {
  std::filesystem::path face_model;       // facemodel.fbfm
  std::filesystem::path shape_predictor;  // dlib's 68-point model
};

// What one capture gives the fit: the frontal colour frame and the fused surface seen from the
// camera that took it.
struct CaptureView {
  ColorImage color;
  Image<float> depth_mm;           // 0 = no surface
  Image<Eigen::Vector3f> normals;  // may be empty (computed from depth)
  Image<float> confidence;         // may be empty (all depth trusted); FitTarget::confidence
  PinholeIntrinsics intrinsics;    // depth camera
  KinectCalibration calibration;   // depth <-> colour registration
};

struct QuickFitResult {
  bool neutral = false;                            // a neutral fit (else an expression fit)
  bool neutral_was_mean_face = false;              // expression fit without a fitted neutral
  std::array<Eigen::Vector2d, 68> color_points{};  // colour px, iBUG order (after corrections)
  std::array<bool, 68> corrected{};
  double detection_score = 0;    // dlib HOG detector margin of the face box (> 0 = confident)
  int landmarks_valid = 0;       // points that landed inside the depth image
  int landmarks_3d = 0;          // interior points lifted to 3D with the fused depth
  double landmark_error_mm = 0;  // landmark_disagreement_mm() of the final fit
  FitTarget target;
  FitResult fit;

  // The landmarks as the store keeps them (colour px, plus the lifted 3D point when there is one).
  std::vector<Landmark> stored_landmarks(const PinholeIntrinsics& depth) const;
};

class QuickFitter {
 public:
  static Result<std::unique_ptr<QuickFitter>> create(const QuickFitPaths& paths,
                                                     const std::vector<GuideStep>& guide);
  ~QuickFitter();
  QuickFitter(const QuickFitter&) = delete;
  QuickFitter& operator=(const QuickFitter&) = delete;

  const FaceModel& model() const;

  // The session whose neutral is loaded (0 = none). Neutral fits set it; set_neutral() loads a
  // stored one (resume, restart).
  std::int64_t neutral_session() const;
  // A stored neutral (its pose is unknown: expression fits then align from the landmarks).
  Result<void> set_neutral(std::int64_t session, std::span<const float> neutral_mesh);
  void forget_neutral();
  // The subject's identity in sigma units (the neutral fit's, or the stored neutral mesh
  // projected onto the identity basis); empty without a neutral.
  const std::vector<float>& identity() const;

  // Landmarks + fit of capture `guide_index` of `session` (0 = the neutral fit, which becomes
  // the session's neutral). Fails only on bad input ("no face found", "no depth in the face
  // box"); the caller turns that into a failed quality check.
  Result<QuickFitResult> fit(std::int64_t session, int guide_index, const CaptureView& view);
  // The same with given colour landmarks instead of detection (a refit from stored data).
  Result<QuickFitResult> fit_with_points(std::int64_t session, int guide_index,
                                         const CaptureView& view,
                                         const std::array<Eigen::Vector2d, 68>& color_points,
                                         double detection_score);
  // Applies corrections to `result` (re-lifts the points) and refits, seeded from the previous
  // fit. A corrected neutral becomes the session's neutral.
  Result<void> refit(std::int64_t session, int guide_index, const CaptureView& view,
                     std::span<const ColorCorrection> corrections, QuickFitResult& result);

  MeshData mesh(const QuickFitResult& result) const;
  double landmark_model_load_ms() const;
  // A detector on the fitter's shape predictor (shared, not reloaded) for another thread: the
  // tracking mode's re-acquisition by detection. The fitter keeps using its own.
  LandmarkDetector share_landmark_detector() const;

  struct State;

 private:
  explicit QuickFitter(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;
};

// Identity coefficients (sigma units) whose model mesh is closest to `neutral_mesh` (model
// frame): ridge least squares over the face vertices, min |B c - (m - mean)|^2 + lambda |c|^2.
std::vector<float> project_identity(const FaceModel& model, std::span<const float> neutral_mesh,
                                    int modes = 100, double lambda = 1.0);

}  // namespace fb
