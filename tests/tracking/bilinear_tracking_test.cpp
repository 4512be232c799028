// Calibration with the bilinear model (issue 6): the tracker fits the identity in the bilinear
// model's identity space and then tracks with the subject's own blendshapes from it.
#include "algo/tracking/bilinear_subject.hpp"

#include <algorithm>
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "algo/bilinear/bootstrap.hpp"
#include "algo/bilinear/tensor_decomposition.hpp"
#include "sim/camera/synthetic_camera.hpp"
#include "tests/common/test_face_model.hpp"

namespace fb {
namespace {

constexpr int kTrainingIdentities = 24;
constexpr int kSubject = 3;            // the tracked subject is this training identity
constexpr float kSubjectScale = 2.0f;  // whose expressions are twice the generic ones
constexpr std::uint64_t kIdentitySeed = 7;

float expression_scale(int identity) {
  return identity == kSubject ? kSubjectScale : 0.9f + 0.01f * static_cast<float>(identity);
}

// A bilinear model whose subjects differ in expression too: the bootstrap tensor of
// kTrainingIdentities face-model identities, with identity i's expression deltas scaled by
// expression_scale(i). All knobs kept (24 x 54), so it reproduces every training subject.
const BilinearModel& scaled_expression_model() {
  static const BilinearModel built = [] {
    const FaceModel& face = test::face_model();
    const auto identities = draw_identities(face, kTrainingIdentities, kIdentitySeed);
    FactoredTensor tensor = bootstrap_tensor(face, identities);
    const Eigen::Index expression_rows = face.fitting_expression_count;
    const Eigen::Index first = tensor.coefficients.rows() - expression_rows;
    for (int e = 1; e < tensor.expressions; ++e) {
      for (int i = 0; i < tensor.identities; ++i) {
        tensor.coefficients.col(static_cast<Eigen::Index>(e) * tensor.identities + i)
            .segment(first, expression_rows) *= expression_scale(i);
      }
    }
    auto factors = mode_factors(tensor);
    EXPECT_TRUE(factors.ok());
    if (!factors) return BilinearModel{};
    auto truncated = truncate(tensor, *factors, kTrainingIdentities, tensor.expressions);
    EXPECT_TRUE(truncated.ok());
    if (!truncated) return BilinearModel{};
    return make_bilinear_model(*truncated, face, bootstrap_expression_names(face), "{}");
  }();
  return built;
}

double max_abs_difference(std::span<const float> a, std::span<const float> b) {
  double worst = 0.0;
  for (std::size_t i = 0; i < a.size() && i < b.size(); ++i)
    worst = std::max(worst, static_cast<double>(std::abs(a[i] - b[i])));
  return worst;
}

TEST(BilinearSubject, TrackingModelAndDeltasReproduceTheBilinearModel) {
  const FaceModel& face = test::face_model();
  const BilinearModel& bilinear = scaled_expression_model();
  auto tracking = make_bilinear_tracking_model(bilinear, face);
  ASSERT_TRUE(tracking.ok()) << tracking.error().message;
  // 24 training identities span 23 directions about their mean.
  EXPECT_EQ(tracking->face.identity_count, kTrainingIdentities - 1);
  EXPECT_EQ(tracking->face.fitting_expression_count, face.fitting_expression_count);
  const BilinearBlendshapes blendshapes(bilinear, *tracking);

  // Some identity in the tracker's coefficients: its neutral is the bilinear model's.
  std::vector<float> c(static_cast<std::size_t>(tracking->face.identity_count));
  std::mt19937 rng(3);
  std::normal_distribution<float> normal(0.0f, 1.0f);
  for (auto& x : c) x = normal(rng);
  const std::vector<float> w = blendshapes.knobs(c);
  const std::size_t n3 = 3 * static_cast<std::size_t>(face.vertex_count);
  std::vector<float> expected(n3), got(n3), shape(n3);
  bilinear.evaluate(w, bilinear.expression_row(0), expected);
  tracking->face.evaluate(c, {}, got);
  EXPECT_LT(max_abs_difference(expected, got), 1e-2);  // mm, float sums over 24 x 54 blocks

  // The subject's deltas at a few vertices: C x_2 w x_3 u_e minus the neutral.
  const std::vector<std::uint32_t> vertices = {
      face.landmark_vertices[48], face.landmark_vertices[57], face.landmark_vertices[19], 5};
  const int k = face.fitting_expression_count;
  std::vector<float> deltas(3 * vertices.size() * static_cast<std::size_t>(k), 0.0f);
  blendshapes.subject_deltas(c, vertices, deltas);
  for (const char* name : {"jawOpen", "mouthSmile_L", "browDown_R"}) {
    const int j = face.expression_index(name);
    ASSERT_GE(j, 0);
    const auto row =
        std::find(bilinear.expression_names.begin(), bilinear.expression_names.end(), name) -
        bilinear.expression_names.begin();
    bilinear.evaluate(w, bilinear.expression_row(static_cast<int>(row)), shape);
    for (std::size_t v = 0; v < vertices.size(); ++v) {
      for (std::size_t a = 0; a < 3; ++a) {
        const std::size_t at = 3 * vertices[v] + a;
        EXPECT_NEAR(deltas[static_cast<std::size_t>(j) * 3 * vertices.size() + 3 * v + a],
                    shape[at] - expected[at], 1e-2)
            << name << " vertex " << vertices[v];
      }
    }
  }

  // Another topology is refused, naming the counts.
  BilinearModel wrong = bilinear;
  wrong.vertex_count = 100;
  auto refused = make_bilinear_tracking_model(wrong, face);
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.error().message.find("100 vertices"), std::string::npos)
      << refused.error().message;
  // So is a model whose expressions are none of the face model's shapes.
  BilinearModel unnamed = bilinear;
  for (std::size_t e = 1; e < unnamed.expression_names.size(); ++e)
    unnamed.expression_names[e] = "pose_" + std::to_string(e);
  auto nameless = make_bilinear_tracking_model(unnamed, face);
  ASSERT_FALSE(nameless.ok());
  EXPECT_NE(nameless.error().message.find("none of the bilinear model's 53 expressions"),
            std::string::npos)
      << nameless.error().message;
}

// Reads jawOpen and mouthSmile_L on the last frames of a take of the training subject kSubject
// (whose expressions are twice the generic ones), calibrated with the bilinear model; with or
// without the subject's own blendshapes.
struct Reading {
  float jaw = 0.0f, smile = 0.0f;
  double neutral_rms_mm = 0.0;  // calibrated neutral against the subject's, face vertices
  bool calibrated = false;
};

Reading track_subject(bool own_blendshapes) {
  const FaceModel& face = test::face_model();
  const BilinearModel& bilinear = scaled_expression_model();
  auto tracking = make_bilinear_tracking_model(bilinear, face);
  EXPECT_TRUE(tracking.ok());
  if (!tracking) return {};
  const BilinearBlendshapes blendshapes(bilinear, *tracking);

  const int jaw = face.expression_index("jawOpen"), smile = face.expression_index("mouthSmile_L");
  SyntheticOptions o;
  o.seed = 11;
  o.identity_coeffs = draw_identities(face, kTrainingIdentities, kIdentitySeed)[kSubject];
  o.personal_expression_basis = face.expression_basis;
  for (auto& x : o.personal_expression_basis) x *= kSubjectScale;
  o.frame_count = 36;
  o.yaw_amplitude_deg = 6.0;
  o.pitch_amplitude_deg = 3.0;
  for (int f = 0; f < o.frame_count; ++f) {
    std::vector<float> weights(static_cast<std::size_t>(face.expression_count), 0.0f);
    if (f >= 16) {  // neutral while calibrating (10 frames) and settling
      weights[static_cast<std::size_t>(jaw)] = 0.3f;
      weights[static_cast<std::size_t>(smile)] = 0.3f;
    }
    o.expression_track.push_back(weights);
  }
  auto camera = make_synthetic_camera(face, o);
  EXPECT_TRUE(camera.ok());
  if (!camera || !(*camera)->start()) return {};

  auto tracker = FaceTracker::create(tracking->face, (*camera)->info().depth_intrinsics);
  EXPECT_TRUE(tracker.ok());
  if (!tracker) return {};
  if (own_blendshapes) (*tracker)->set_subject_blendshapes(&blendshapes);
  RgbdFrame frame;
  TrackReport report;
  Reading out;
  int averaged = 0;
  for (int f = 0; f < o.frame_count; ++f) {
    auto status = (*camera)->next_frame(frame, std::chrono::milliseconds(1000));
    EXPECT_TRUE(status.ok() && *status == FrameStatus::kFrame);
    if (!status || *status != FrameStatus::kFrame) break;
    (*tracker)->track(frame.depth_mm, f / 30.0, nullptr, report);
    if (f >= o.frame_count - 8) {
      out.jaw += report.weights[static_cast<std::size_t>(jaw)];
      out.smile += report.weights[static_cast<std::size_t>(smile)];
      ++averaged;
    }
  }
  out.jaw /= static_cast<float>(std::max(averaged, 1));
  out.smile /= static_cast<float>(std::max(averaged, 1));
  out.calibrated = (*tracker)->calibrated();
  const std::size_t n3 = 3 * static_cast<std::size_t>(face.vertex_count);
  std::vector<float> truth(n3), fitted(n3);
  face.evaluate(*o.identity_coeffs, {}, truth);
  tracking->face.evaluate((*tracker)->identity(), {}, fitted);
  double sum = 0.0;
  for (int v = 0; v < face.face_vertex_count; ++v) {
    for (int a = 0; a < 3; ++a) {
      const double d = truth[3 * v + a] - fitted[3 * v + a];
      sum += d * d;
    }
  }
  out.neutral_rms_mm = std::sqrt(sum / face.face_vertex_count);
  return out;
}

TEST(BilinearSubject, TrackerUsesTheCalibratedSubjectsOwnBlendshapes) {
  const Reading own = track_subject(true);
  ASSERT_TRUE(own.calibrated);
  // The subject's neutral is found in the bilinear identity space (0.19 mm rms here) and the
  // weights are the true ones (0.311 and 0.288 here).
  EXPECT_LT(own.neutral_rms_mm, 1.0);
  EXPECT_NEAR(own.jaw, 0.3f, 0.04f);
  EXPECT_NEAR(own.smile, 0.3f, 0.04f);
  // The mean identity's blendshapes (about the generic ones) read the subject's twice-as-large
  // motion as about twice the weight (0.57 and 0.53 here): what the subject's own blendshapes
  // are for.
  const Reading mean = track_subject(false);
  ASSERT_TRUE(mean.calibrated);
  EXPECT_GT(mean.jaw, 0.45f);
  EXPECT_GT(mean.smile, 0.45f);
}

}  // namespace
}  // namespace fb
