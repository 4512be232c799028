// The photo pipeline (algo/photo, host/cli/photo_pipeline): the mesh warp on known moves; a
// take's ARKit curves on the model's shapes; a synthetic textured face animated by a jaw-open
// and a smile, its frames against the truth renders (dlib on both, the projected landmarks);
// the face_length edit measured by re-fitting the edited photo.
#include <gtest/gtest.h>

#include <cstdio>

#include "algo/photo/photo_face.hpp"
#include "host/cli/photo_pipeline.hpp"
#include "host/cli/tracker_setup.hpp"
#include "storage/take_writer.hpp"
#include "tests/photo/photo_fixture.hpp"

namespace fb {
namespace {

// A square of two triangles over a checker photo.
struct Square {
  std::vector<std::uint32_t> triangles{0, 1, 2, 0, 2, 3};
  std::vector<Eigen::Vector2f> source{{40, 40}, {80, 40}, {80, 80}, {40, 80}};
};

ColorImage checker(int w, int h) {
  ColorImage img;
  img.resize(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      img.at(x, y) = {static_cast<std::uint8_t>(((x / 4 + y / 4) % 2) * 200 + 20),
                      static_cast<std::uint8_t>(x * 2), static_cast<std::uint8_t>(y * 2)};
  return img;
}

int channel_difference(Rgb8 a, Rgb8 b) {
  return std::max({std::abs(a.r - b.r), std::abs(a.g - b.g), std::abs(a.b - b.b)});
}

TEST(MeshWarp, UnmovedMeshGivesThePhotoBack) {
  const ColorImage photo = checker(120, 120);
  Square s;
  std::vector<Eigen::Vector3f> target;
  for (const auto& p : s.source) target.emplace_back(p.x(), p.y(), 0.0f);
  MeshWarpStats stats;
  auto out = warp_photo(photo, {s.triangles, s.source, target, {}}, {}, &stats);
  ASSERT_TRUE(out.ok()) << out.error().message;
  EXPECT_GT(stats.covered_pixels, 40 * 40);
  int worst = 0;
  for (std::size_t k = 0; k < photo.pixels.size(); ++k)
    worst = std::max(worst, channel_difference(photo.pixels[k], out->pixels[k]));
  EXPECT_EQ(worst, 0);
}

TEST(MeshWarp, MovedMeshCarriesItsPixelsAndKeepsTheFarBackground) {
  const ColorImage photo = checker(120, 120);
  Square s;
  std::vector<Eigen::Vector3f> target;
  for (const auto& p : s.source) target.emplace_back(p.x() + 6, p.y() + 3, 0.0f);
  MeshWarpStats stats;
  auto out = warp_photo(photo, {s.triangles, s.source, target, {}}, {}, &stats);
  ASSERT_TRUE(out.ok());
  EXPECT_NEAR(stats.max_shift_px, std::hypot(6.0, 3.0), 1e-3);
  int inside = 0, far = 0;
  for (int y = 45; y <= 80; ++y)  // inside the moved square: the photo 6, 3 px up-left
    for (int x = 48; x <= 84; ++x)
      inside = std::max(inside, channel_difference(out->at(x, y), photo.at(x - 6, y - 3)));
  for (int y = 0; y < 120; ++y)  // beyond the fade (0.35 x 40 px) and the blur: untouched
    for (int x = 0; x < 120; ++x)
      if (x < 28 || x > 104 || y < 25 || y > 101)
        far = std::max(far, channel_difference(out->at(x, y), photo.at(x, y)));
  EXPECT_EQ(inside, 0);
  EXPECT_EQ(far, 0);
  // Triangles past the vertices are refused.
  std::vector<std::uint32_t> bad{0, 1, 7};
  EXPECT_FALSE(warp_photo(photo, {bad, s.source, target, {}}).ok());
}

TEST(MeshWarp, MouthOpeningIsTheCavityColour) {
  const ColorImage photo = checker(120, 120);
  Square s;
  std::vector<Eigen::Vector3f> target;
  for (const auto& p : s.source) target.emplace_back(p.x(), p.y(), 0.0f);
  const std::vector<Eigen::Vector2f> mouth{{90, 90}, {110, 90}, {110, 110}, {90, 110}};
  MeshWarpOptions o;
  MeshWarpStats stats;
  auto out = warp_photo(photo, {s.triangles, s.source, target, mouth}, o, &stats);
  ASSERT_TRUE(out.ok());
  EXPECT_GE(stats.mouth_pixels, 19 * 19);
  EXPECT_EQ(channel_difference(out->at(100, 100), o.mouth_color), 0);
}

TEST(TakeCoefficients, ArkitCurvesReachTheModelShapes) {
  const BilinearModel& m = test::photo_model();
  TakeWriter w(std::vector<std::string>(kArkitNames.begin(), kArkitNames.end()), 30);
  ASSERT_TRUE(
      w.add_frame(0, RigidPose{}, test::arkit_curves({{"jawOpen", 0.5f}, {"browInnerUp", 0.8f}}))
          .ok());
  auto c = cli::take_coefficients(w.data(), m);
  ASSERT_TRUE(c.ok()) << c.error().message;
  auto beta_of = [&](const std::string& name) {
    const auto it = std::find(m.expression_names.begin(), m.expression_names.end(), name);
    return c->beta[0][static_cast<std::size_t>(it - m.expression_names.begin() - 1)];
  };
  EXPECT_FLOAT_EQ(beta_of("jawOpen"), 0.5f);
  EXPECT_FLOAT_EQ(beta_of("browInnerUp_L"), 0.8f);  // a combined curve feeds both halves
  EXPECT_FLOAT_EQ(beta_of("browInnerUp_R"), 0.8f);
  EXPECT_FLOAT_EQ(beta_of("eyeBlink_L"), 0.0f);
  EXPECT_EQ(c->mapped_shapes, 53);  // every fitting shape; the take has no tongue
  // A take with none of the model's shapes is refused.
  TakeWriter other(std::vector<std::string>{"foo", "bar"}, 30);
  ASSERT_TRUE(other.add_frame(0, RigidPose{}, std::vector<float>{1, 1}).ok());
  EXPECT_FALSE(cli::take_coefficients(other.data(), m).ok());
}

double mean_inner(const std::array<Eigen::Vector2d, 68>& a,
                  const std::array<Eigen::Vector2d, 68>& b) {
  double s = 0;
  for (int k = 17; k < 68; ++k) s += (a[k] - b[k]).norm();
  return s / 51;
}

TEST(PhotoAnimation, FramesFollowTheTruthRenderOfTheSameExpression) {
  const BilinearModel& m = test::photo_model();
  const auto jaw = test::arkit_curves({{"jawOpen", 0.7f}});
  const auto smile = test::arkit_curves({{"mouthSmileLeft", 0.9f}, {"mouthSmileRight", 0.9f}});
  const auto r = test::render_faces(
      7, {test::model_weights({}), test::model_weights(jaw), test::model_weights(smile)});
  auto detector = cli::load_landmark_detector("");
  ASSERT_TRUE(detector.ok()) << detector.error().message;
  auto points = cli::detect_photo_landmarks(*detector, r.frames[0], "photo");
  ASSERT_TRUE(points.ok()) << points.error().message;
  auto face = fit_photo_face(m, *points);
  ASSERT_TRUE(face.ok()) << face.error().message;
  EXPECT_LT(face->fit.mean_error_px, 3.0);
  TakeWriter take(std::vector<std::string>(kArkitNames.begin(), kArkitNames.end()), 30);
  ASSERT_TRUE(take.add_frame(0, RigidPose{}, jaw).ok());
  ASSERT_TRUE(take.add_frame(1, RigidPose{}, smile).ok());
  auto c = cli::take_coefficients(take.data(), m);
  ASSERT_TRUE(c.ok());
  const auto triangles = face_region_triangles(m);
  std::vector<float> mesh;
  for (int f = 0; f < 2; ++f) {
    auto frame = cli::animate_photo_frame(r.frames[0], m, *face, triangles, c->beta[f], true, mesh);
    ASSERT_TRUE(frame.ok()) << frame.error().message;
    auto produced = cli::detect_photo_landmarks(*detector, *frame, "frame");
    auto truth = cli::detect_photo_landmarks(*detector, r.frames[f + 1], "truth");
    ASSERT_TRUE(produced.ok() && truth.ok());
    std::array<Eigen::Vector2d, 68> projected;
    for (int k = 0; k < 68; ++k) {
      const auto v = m.landmark_vertices[k];
      projected[k] = face->fit.pose.project({mesh[3 * v], mesh[3 * v + 1], mesh[3 * v + 2]});
    }
    const double dlib_px = mean_inner(produced->points, truth->points);
    const double projected_px = mean_inner(projected, r.truth[f + 1]);
    const double baseline_px = mean_inner(points->points, truth->points);
    const double motion_px = mean_inner(r.truth[0], r.truth[f + 1]);
    std::printf("frame %d: dlib %.2f px, projected %.2f px, unanimated %.2f px, motion %.2f px\n",
                f, dlib_px, projected_px, baseline_px, motion_px);
    EXPECT_LT(dlib_px, 3.0);
    EXPECT_LT(projected_px, 3.0);
    EXPECT_LT(dlib_px, 0.6 * baseline_px);  // the animation moved the face the right way
  }
}

TEST(PhotoVideo, JointFitRecoversTheJawOfAPerformersFrames) {
  // FaceWarehouse 4.4: a performer's frames (neutral, jaw open 0.7, neutral) -> coefficients.
  const BilinearModel& m = test::photo_model();
  const auto jaw = test::arkit_curves({{"jawOpen", 0.7f}});
  const auto r = test::render_faces(
      21, {test::model_weights({}), test::model_weights(jaw), test::model_weights({})});
  auto detector = cli::load_landmark_detector("");
  ASSERT_TRUE(detector.ok());
  std::vector<ImageLandmarks> points(3);
  for (int f = 0; f < 3; ++f) {
    auto l = cli::detect_photo_landmarks(*detector, r.frames[f], "frame");
    ASSERT_TRUE(l.ok());
    points[f] = *l;
  }
  auto c = cli::video_coefficients(m, points, {true, true, true});
  ASSERT_TRUE(c.ok()) << c.error().message;
  ASSERT_EQ(c->coefficients.beta.size(), 3u);
  const auto at = [&](int f, const std::string& name) {
    const auto it = std::find(m.expression_names.begin(), m.expression_names.end(), name);
    return c->coefficients.beta[f][static_cast<std::size_t>(it - m.expression_names.begin() - 1)];
  };
  double others = 0;
  for (std::size_t i = 0; i < c->coefficients.beta[1].size(); ++i)
    others = std::max(others, static_cast<double>(c->coefficients.beta[1][i]));
  std::printf("joint fit %.2f px; jawOpen %.2f (truth 0.7), neutral after %.2f, largest %.2f\n",
              c->mean_fit_error_px, at(1, "jawOpen"), at(2, "jawOpen"), others);
  EXPECT_LT(c->mean_fit_error_px, 3.0);
  EXPECT_EQ(at(0, "jawOpen"), 0.0f);  // the first frame is the neutral
  EXPECT_GT(at(1, "jawOpen"), 0.3f);
  EXPECT_LT(at(2, "jawOpen"), 0.15f);
}

TEST(PhotoEdit, FaceLengthChangeIsMeasuredOnTheEditedPhoto) {
  const BilinearModel& m = test::photo_model();
  const auto r = test::render_faces(9, {test::model_weights({})});
  auto detector = cli::load_landmark_detector("");
  ASSERT_TRUE(detector.ok());
  auto points = cli::detect_photo_landmarks(*detector, r.frames[0], "photo");
  ASSERT_TRUE(points.ok());
  auto face = fit_photo_face(m, *points);
  ASSERT_TRUE(face.ok());
  const auto attributes = default_attributes();
  auto reg = fit_attribute_regression(m, attributes);
  ASSERT_TRUE(reg.ok());
  std::vector<double> change(attributes.size(), 0.0);
  change[0] = 10.0;
  const auto w_id = apply_attribute_change(*reg, face->fit.w_id, change);
  std::vector<float> edited(face->mesh.size());
  m.evaluate(w_id, face->fit.w_exp, edited);
  auto image = warp_face(r.frames[0], m, face->fit.pose, face->mesh, edited,
                         face_region_triangles(m), MeshWarpOptions{.mouth_cavity = false});
  ASSERT_TRUE(image.ok());
  auto after = cli::detect_photo_landmarks(*detector, *image, "edited");
  ASSERT_TRUE(after.ok());
  auto length_px = [](const ImageLandmarks& l) { return (l.points[27] - l.points[8]).norm(); };
  const double dlib_mm = (length_px(*after) - length_px(*points)) / face->fit.pose.scale;
  auto refit = fit_photo_face(m, *after);
  ASSERT_TRUE(refit.ok());
  std::vector<float> neutral(face->mesh.size());
  auto length_mm = [&](std::span<const float> id) {
    m.evaluate(id, m.expression_row(0), neutral);
    return measure_attributes(neutral, m.landmark_vertices, attributes)[0];
  };
  const double model_mm = length_mm(w_id) - length_mm(face->fit.w_id);
  const double refit_mm = (refit->fit.pose.scale * length_mm(refit->fit.w_id) -
                           face->fit.pose.scale * length_mm(face->fit.w_id)) /
                          face->fit.pose.scale;
  std::printf("face_length +10 mm: model %.2f, dlib on the edited photo %.2f, re-fit %.2f mm\n",
              model_mm, dlib_mm, refit_mm);
  EXPECT_NEAR(model_mm, 10.0, 1.0);
  EXPECT_NEAR(dlib_mm, 10.0, 4.0);
  // The re-fit sees part of it: the identity prior holds a fit from 68 points near the mean.
  EXPECT_GT(refit_mm, 3.0);
}

}  // namespace
}  // namespace fb
