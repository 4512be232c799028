// The bilinear model (algo/bilinear) as the tracker's subject model (issue 6: "fit identity
// from the first frames with the bilinear model ... and build their blendshapes").
//
// The tracker calibrates a linear identity space, so the bilinear model's neutral is written
// as one: with U_id's rows w_i the training identities,
//
//   neutral(w) = C x_2 w x_3 u_0 = M w,   w = w_mean + Q sqrt(L) c,   c ~ N(0, I),
//
// where Q L Q^T is the covariance of the rows (their principal directions), so the tracker's
// identity prior in sigma units is the training population's. The expression deltas of the
// tracking FaceModel are those of the mean identity (used before calibration); once c is
// calibrated, BilinearBlendshapes gives the subject's own, C x_2 w x_3 (u_e - u_0).
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "algo/bilinear/bilinear_model.hpp"
#include "algo/core/result.hpp"
#include "algo/facemodel/face_model.hpp"
#include "algo/tracking/face_tracker.hpp"

namespace fb {

struct BilinearTrackingModel {
  // The tracker's model: the topology's triangles, landmarks and vertex subsets; neutral,
  // identity modes and expression deltas from the bilinear model (shapes the bilinear model
  // does not name keep the topology's deltas).
  FaceModel face;
  std::vector<float> mean_identity;  // w_mean, id_knobs
  Eigen::MatrixXf knobs_per_mode;    // id_knobs x face.identity_count: Q sqrt(L)
  // Per fitting shape of `face`: its row of U_exp, or -1 when the bilinear model lacks it.
  std::vector<int> expression_row;
};

// Fails when the models do not share the topology (vertex counts, landmark vertices) or the
// bilinear model has no neutral, naming the mismatch.
Result<BilinearTrackingModel> make_bilinear_tracking_model(const BilinearModel& bilinear,
                                                           const FaceModel& topology);

// The subject's blendshapes for the tracker (set_subject_blendshapes). Both models must
// outlive it.
class BilinearBlendshapes final : public SubjectBlendshapes {
 public:
  BilinearBlendshapes(const BilinearModel& bilinear, const BilinearTrackingModel& tracking)
      : bilinear_(bilinear), tracking_(tracking) {}
  void subject_deltas(std::span<const float> identity, std::span<const std::uint32_t> vertices,
                      std::span<float> deltas) const override;
  // The subject's knobs w = w_mean + Q sqrt(L) c for tracker coefficients c.
  std::vector<float> knobs(std::span<const float> identity) const;

 private:
  const BilinearModel& bilinear_;
  const BilinearTrackingModel& tracking_;
};

}  // namespace fb
