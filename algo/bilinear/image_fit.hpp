// Using the bilinear model on images (FaceWarehouse sections 4.1-4.4):
//
//  - fit_landmarks: weak-perspective projection p_k = s R v_k + t (eq. 13) of the model's
//    landmark vertices, v = C_r x_2 w_id x_3 w_exp, fitted to 2D landmarks (eq. 14) by
//    coordinate descent: pose (s, R, t) by Gauss-Newton from an affine start, then w_id with the
//    rest fixed (linear least squares), then w_exp (likewise), repeated. Both weight solves carry
//    a Gaussian prior from the training rows of U_id / U_exp (mean and per-knob variance),
//    lambda * sum_a (w_a - mean_a)^2 / var_a, which also pins the scale ambiguity between s and
//    |w_id| that weak perspective leaves.
//  - fit_landmarks_joint: one identity shared by several images or video frames (eq. 15, 4.4):
//    independent fits first, then alternately w_id over all images and each image's pose and
//    w_exp, for `rounds` rounds.
//  - image_blendshapes: B_i = C_r x_2 w_id x_3 U~_exp[i] (eq. 17).
//  - Attribute regression (4.1.1): attributes measured on each training identity's neutral mesh,
//    M_fea = W_id F^+ (eq. 11-12), and an attribute change df maps to dw_id = M_fea [df; 0].
//
// The jawline landmarks use fixed vertices (no silhouette sliding): fine for near-frontal views.
#pragma once

#include <array>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "algo/bilinear/bilinear_model.hpp"
#include "algo/core/result.hpp"

namespace fb {

struct WeakPerspectivePose {
  double scale = 1.0;
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector2d translation = Eigen::Vector2d::Zero();
  Eigen::Vector2d project(const Eigen::Vector3d& v) const {
    return scale * (rotation * v).head<2>() + translation;
  }
};

struct ImageLandmarks {
  std::array<Eigen::Vector2d, 68> points{};
  std::array<bool, 68> valid{};  // missing points are skipped
};

struct LandmarkFitOptions {
  int iterations = 12;            // coordinate-descent rounds
  double identity_prior = 1.0;    // lambda_id (px^2 per unit Mahalanobis distance)
  double expression_prior = 0.2;  // lambda_exp
  int pose_iterations = 8;        // Gauss-Newton steps per pose update
};

struct LandmarkFit {
  WeakPerspectivePose pose;
  std::vector<float> w_id;   // Kid
  std::vector<float> w_exp;  // Kexp
  double mean_error_px = 0;  // mean distance of the projected landmarks to the given ones
  std::vector<double> error_history_px;  // after each round
};

Result<LandmarkFit> fit_landmarks(const BilinearModel& model, const ImageLandmarks& landmarks,
                                  const LandmarkFitOptions& options = {});

struct JointLandmarkFit {
  std::vector<float> w_id;
  std::vector<LandmarkFit> images;  // per image: pose, w_exp, error (w_id is the shared one)
  double mean_error_px = 0;
};

Result<JointLandmarkFit> fit_landmarks_joint(const BilinearModel& model,
                                             std::span<const ImageLandmarks> images,
                                             const LandmarkFitOptions& options = {},
                                             int rounds = 3);

// Eq. 17: one mesh (3V floats) per model expression (U~_exp rows) for the identity w_id.
std::vector<std::vector<float>> image_blendshapes(const BilinearModel& model,
                                                  std::span<const float> w_id);

// A user attribute: the distance between two landmark vertices of the neutral mesh, in mm.
struct AttributeDefinition {
  std::string name;
  int landmark_a = 0;
  int landmark_b = 0;
};
// face_length, face_width, mouth_width, nose_width, nose_length, eye_distance.
std::vector<AttributeDefinition> default_attributes();
std::vector<double> measure_attributes(std::span<const float> mesh,
                                       const std::array<std::uint32_t, 68>& landmark_vertices,
                                       std::span<const AttributeDefinition> attributes);

struct AttributeRegression {
  std::vector<AttributeDefinition> attributes;
  Eigen::MatrixXd mapping;  // M_fea, Kid x (l + 1)
};

// Regresses the training identities (rows of U_id, neutral expression U~_exp[0]). Needs more
// identities than attributes.
Result<AttributeRegression> fit_attribute_regression(
    const BilinearModel& model, std::span<const AttributeDefinition> attributes);
// w_id + M_fea [df; 0].
std::vector<float> apply_attribute_change(const AttributeRegression& regression,
                                          std::span<const float> w_id,
                                          std::span<const double> attribute_change);

}  // namespace fb
