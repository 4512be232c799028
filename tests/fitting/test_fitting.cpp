// Face fitting against rendered ground truth: the model with a known identity, expression and
// pose is rasterised into a depth map (noise-free, so the tests are fast and deterministic; the
// sensor + fusion path is scored by `facebooth-lab eval fit`), with exact landmarks.
#include <gtest/gtest.h>

#include <array>
#include <random>

#include "algo/fitting/expression_transfer.hpp"
#include "algo/fitting/face_fit.hpp"
#include "algo/fitting/fit_qa.hpp"
#include "algo/fitting/mesh_ops.hpp"
#include "algo/render/rasterizer.hpp"
#include "storage/asset_files.hpp"
#include "tests/common/test_face_model.hpp"
#include "tests/fitting/fit_scene.hpp"

namespace fb {
namespace {

// The image row of the highest brow landmark (17-26).
double top_of_brows_px(const FitTarget& target) {
  double y = 1e9;
  for (int l = 17; l <= 26; ++l) y = std::min(y, target.landmarks[l].pixel.y());
  return y;
}

double pose_angle_deg(const RigidPose& a, const RigidPose& b) {
  return a.rotation.angularDistance(b.rotation) * 180 / M_PI;
}

TEST(Fitting, NeutralFitRecoversIdentityAndPose) {
  const auto identity = random_identity(3);
  const auto truth = face(identity);
  const RigidPose pose = truth_pose(truth);
  const FitTarget target = render_target(truth, pose, 1.0);
  auto fit = fit_neutral(test::face_model(), target);
  ASSERT_TRUE(fit.ok()) << fit.error().message;
  const double initial = mean_vertex_distance(fit->initial_vertices, fit->camera_from_model, truth,
                                              pose, test::face_model().fitting_vertices);
  const double refined = mean_vertex_distance(fit->vertices, fit->camera_from_model, truth, pose,
                                              test::face_model().fitting_vertices);
  const auto mean_face = face({});
  const double untouched =
      mean_vertex_distance(mean_face, pose, truth, pose, test::face_model().fitting_vertices);
  std::printf(
      "neutral: mean face %.2f mm, step 1 %.3f mm, refined %.3f mm; RMS to depth %.3f -> %.3f mm; "
      "pose %.3f deg; %.0f + %.0f ms\n",
      untouched, initial, refined, fit->rms_to_depth_mm_initial, fit->rms_to_depth_mm,
      pose_angle_deg(fit->camera_from_model, pose), fit->times.initial_ms, fit->times.refine_ms);
  EXPECT_LT(initial, 1.0);
  EXPECT_LT(refined, 1.0);
  EXPECT_LT(initial, 0.5 * untouched);
  EXPECT_LT(pose_angle_deg(fit->camera_from_model, pose), 1.0);
  // Identity coefficients: the leading modes are recovered.
  for (int k = 0; k < 5; ++k)
    EXPECT_NEAR(fit->identity_coeffs[k], identity[k], 0.5) << "mode " << k;
  // Per-vertex residuals are reported for the face.
  ASSERT_EQ(fit->vertex_residual_mm.size(),
            static_cast<std::size_t>(test::face_model().vertex_count));
  EXPECT_GT(fit->depth_correspondences, 3000);
}

TEST(Fitting, RefinementReducesResidual) {
  // A face outside the PCA span (identity + an expression the neutral fit cannot explain).
  std::vector<float> w(static_cast<std::size_t>(test::face_model().expression_count), 0.0f);
  w[test::face_model().expression_index("cheekPuff_L")] = 0.6f;
  const auto truth = face(random_identity(5), w);
  const RigidPose pose = truth_pose(truth, -5.0);
  const FitTarget target = render_target(truth, pose);
  auto fit = fit_neutral(test::face_model(), target);
  ASSERT_TRUE(fit.ok()) << fit.error().message;
  std::printf("RMS to depth: %.3f -> %.3f mm\n", fit->rms_to_depth_mm_initial,
              fit->rms_to_depth_mm);
  EXPECT_LT(fit->rms_to_depth_mm, 0.6 * fit->rms_to_depth_mm_initial);
  EXPECT_LT(fit->rms_to_depth_mm, 0.3);
}

TEST(Fitting, DeformationTransferReproducesKnownDeformation) {
  std::vector<float> w(static_cast<std::size_t>(test::face_model().expression_count), 0.0f);
  w[test::face_model().expression_index("jawOpen")] = 0.6f;
  w[test::face_model().expression_index("mouthSmile_L")] = 0.5f;
  const auto g0 = face({});
  const auto gi = face({}, w);
  // Onto G0 itself: the transfer must give Gi back.
  {
    auto tr = ExpressionTransfer::create(test::face_model(), g0, g0);
    ASSERT_TRUE(tr.ok()) << tr.error().message;
    auto s = tr->transfer(gi);
    ASSERT_TRUE(s.ok());
    const double err = mean_vertex_distance(*s, {}, gi, {}, test::face_model().fitting_vertices);
    std::printf("transfer onto G0: mean %.4f mm\n", err);
    EXPECT_LT(err, 0.05);
  }
  // Onto another identity: near that identity with the same expression weights. Transfer keeps
  // deformation gradients, not absolute deltas, so it is not exact there (measured 1.41 mm of a
  // 3.49 mm expression motion); the bound checks that it carries most of the motion.
  {
    const auto id = random_identity(9);
    const auto s0 = face(id);
    const auto truth = face(id, w);
    auto tr = ExpressionTransfer::create(test::face_model(), s0, g0);
    ASSERT_TRUE(tr.ok());
    auto s = tr->transfer(gi);
    ASSERT_TRUE(s.ok());
    const double err = mean_vertex_distance(*s, {}, truth, {}, test::face_model().fitting_vertices);
    const double moved =
        mean_vertex_distance(s0, {}, truth, {}, test::face_model().fitting_vertices);
    std::printf("transfer onto identity: mean %.3f mm (expression moves %.3f mm)\n", err, moved);
    EXPECT_LT(err, 0.5 * moved);
  }
}

TEST(Fitting, ExpressionFitFromTransfer) {
  std::vector<float> w(static_cast<std::size_t>(test::face_model().expression_count), 0.0f);
  w[test::face_model().expression_index("jawOpen")] = 0.4f;
  w[test::face_model().expression_index("browInnerUp_L")] = 0.8f;
  w[test::face_model().expression_index("browInnerUp_R")] = 0.8f;
  const auto id = random_identity(11);
  const auto neutral_truth = face(id);
  auto neutral =
      fit_neutral(test::face_model(), render_target(neutral_truth, truth_pose(neutral_truth)));
  ASSERT_TRUE(neutral.ok());
  auto tr = ExpressionTransfer::create(test::face_model(), neutral->vertices, face({}));
  ASSERT_TRUE(tr.ok());
  const auto truth = face(id, w);
  const RigidPose pose = truth_pose(truth, 4.0);
  ExpressionFitOptions transferred;
  transferred.start = ExpressionStart::kDeformationTransfer;
  auto fit = fit_expression(test::face_model(), *tr, face({}, w), render_target(truth, pose, 1.0),
                            transferred);
  ASSERT_TRUE(fit.ok()) << fit.error().message;
  const double vi = mean_vertex_distance(fit->initial_vertices, fit->camera_from_model, truth, pose,
                                         test::face_model().fitting_vertices);
  const double vr = mean_vertex_distance(fit->vertices, fit->camera_from_model, truth, pose,
                                         test::face_model().fitting_vertices);
  std::printf("expression: start %.3f mm, refined %.3f mm, RMS %.3f -> %.3f mm, %.0f ms\n", vi, vr,
              fit->rms_to_depth_mm_initial, fit->rms_to_depth_mm, fit->times.total_ms());
  // One hard case (jaw open 0.4 + brows, 4 deg off the neutral's pose, noiseless render).
  // Posed on the face vertices this expression leaves still (not the model's rigid subset,
  // which the render barely shows), with each recipe part scaled to the capture, the start is
  // 0.31 mm and the refinement 0.29 mm (the recipe as it stands: 0.62 / 0.60; with the rigid
  // subset: 0.84 / 0.75).
  EXPECT_LT(vi, 0.45);
  EXPECT_LT(vr, vi);
  EXPECT_LT(fit->rms_to_depth_mm, fit->rms_to_depth_mm_initial);
  EXPECT_LT(fit->rms_to_depth_mm, 0.3);
}

// A face far from the mean (three modes at 3.5 sigma, the rest 1.6x) opening the mouth as the
// face model composes it: the model's shapes added to the fitted neutral start near the truth;
// deformation transfer scales the motion by this face's proportions and starts far from it.
TEST(Fitting, ExpressionStartsFromTheModelsShapesOnAFaceFarFromTheMean) {
  const FaceModel& model = test::face_model();
  std::vector<float> id = random_identity(13, 1.6f);
  for (int k = 0; k < 3; ++k) id[k] = id[k] < 0 ? -3.5f : 3.5f;
  std::vector<float> recipe(static_cast<std::size_t>(model.expression_count), 0.0f);
  std::vector<std::vector<float>> parts;
  for (const auto& [name, weight] : std::initializer_list<std::pair<const char*, float>>{
           {"jawOpen", 0.7f}, {"mouthStretch_L", 0.4f}, {"mouthStretch_R", 0.4f}}) {
    std::vector<float> w(recipe.size(), 0.0f);
    w[model.expression_index(name)] = weight;
    recipe[model.expression_index(name)] = weight;
    parts.push_back(face({}, w));
  }
  const auto neutral_truth = face(id);
  auto neutral = fit_neutral(model, render_target(neutral_truth, truth_pose(neutral_truth)));
  ASSERT_TRUE(neutral.ok());
  auto tr = ExpressionTransfer::create(model, neutral->vertices, face({}));
  ASSERT_TRUE(tr.ok());
  const auto truth = face(id, recipe);
  const RigidPose pose = truth_pose(truth, 4.0);
  const FitTarget target = render_target(truth, pose, 1.0);
  ExpressionFitOptions transferred;
  transferred.start = ExpressionStart::kDeformationTransfer;
  auto from_model = fit_expression(model, *tr, face({}, recipe), target, {}, std::nullopt, parts);
  auto from_transfer =
      fit_expression(model, *tr, face({}, recipe), target, transferred, std::nullopt, parts);
  ASSERT_TRUE(from_model.ok() && from_transfer.ok());
  const auto err = [&](const FitResult& f, bool start) {
    return mean_vertex_distance(start ? f.initial_vertices : f.vertices, f.camera_from_model, truth,
                                pose, model.fitting_vertices);
  };
  const double neutral_error =
      mean_vertex_distance(neutral->vertices, neutral->camera_from_model, neutral_truth,
                           truth_pose(neutral_truth), model.fitting_vertices);
  std::printf(
      "far face opening the mouth: neutral %.3f mm; model's shapes start %.3f -> %.3f mm, "
      "transfer start %.3f -> %.3f mm\n",
      neutral_error, err(*from_model, true), err(*from_model, false), err(*from_transfer, true),
      err(*from_transfer, false));
  EXPECT_LT(err(*from_model, false), 0.7 * err(*from_transfer, false));
  EXPECT_LT(err(*from_model, false), neutral_error + 0.15);
}

// A person opens the jaw less than the guide's recipe says (jawOpen 0.24 for the recipe's 0.4,
// brows as the recipe). The refinement keeps the start's shape and follows depth only within its
// gate; scaling each recipe part to the capture first finds how far the jaw opened.
TEST(Fitting, ExpressionPartsAreScaledToHowThePersonMadeThem) {
  const FaceModel& model = test::face_model();
  const int jaw = model.expression_index("jawOpen");
  const int brow_l = model.expression_index("browInnerUp_L");
  const int brow_r = model.expression_index("browInnerUp_R");
  std::vector<float> recipe(static_cast<std::size_t>(model.expression_count), 0.0f);
  recipe[jaw] = 0.4f;
  recipe[brow_l] = recipe[brow_r] = 0.8f;
  std::vector<std::vector<float>> parts;
  for (const int k : {jaw, brow_l, brow_r}) {
    std::vector<float> w(recipe.size(), 0.0f);
    w[k] = recipe[k];
    parts.push_back(face({}, w));
  }
  const auto id = random_identity(11);
  const auto neutral_truth = face(id);
  auto neutral = fit_neutral(model, render_target(neutral_truth, truth_pose(neutral_truth)));
  ASSERT_TRUE(neutral.ok());
  auto tr = ExpressionTransfer::create(model, neutral->vertices, face({}));
  ASSERT_TRUE(tr.ok());
  std::vector<float> made = recipe;
  made[jaw] = 0.24f;
  const auto truth = face(id, made);
  const RigidPose pose = truth_pose(truth, 4.0);
  const FitTarget target = render_target(truth, pose, 1.0);
  ExpressionFitOptions as_recipe;
  as_recipe.scale_parts = false;
  auto plain = fit_expression(model, *tr, face({}, recipe), target, as_recipe, std::nullopt, parts);
  auto scaled = fit_expression(model, *tr, face({}, recipe), target, {}, std::nullopt, parts);
  ASSERT_TRUE(plain.ok() && scaled.ok());
  const auto err = [&](const FitResult& f) {
    return mean_vertex_distance(f.vertices, f.camera_from_model, truth, pose,
                                model.fitting_vertices);
  };
  ASSERT_EQ(scaled->part_amplitudes.size(), 3u);
  EXPECT_TRUE(plain->part_amplitudes.empty());
  std::printf(
      "jaw made at 0.6 of the recipe: amplitudes %.2f %.2f %.2f, error %.3f mm (as the "
      "recipe %.3f mm)\n",
      scaled->part_amplitudes[0], scaled->part_amplitudes[1], scaled->part_amplitudes[2],
      err(*scaled), err(*plain));
  EXPECT_NEAR(scaled->part_amplitudes[0], 0.6, 0.15);
  EXPECT_NEAR(scaled->part_amplitudes[1], 1.0, 0.2);
  EXPECT_NEAR(scaled->part_amplitudes[2], 1.0, 0.2);
  EXPECT_LT(err(*scaled), 0.7 * err(*plain));
}

// The device's QA (fit_qa.hpp) on fits whose landmarks are right, have a few wild points, or are
// all misplaced: only the last is flagged.
TEST(FitQa, MisplacedLandmarksFailAFewWildPointsDoNot) {
  const auto truth = face(random_identity(5));
  const RigidPose pose = truth_pose(truth);
  FitTarget good = render_target(truth, pose, 1.0);
  auto fit = fit_neutral(test::face_model(), good);
  ASSERT_TRUE(fit.ok());
  const double right = landmark_disagreement_mm(*fit, good);
  FitTarget wild = good;
  for (int l : {48, 54, 57, 62, 66, 8}) {  // an open mouth dlib misreads, and the chin
    wild.landmarks[l].pixel += Eigen::Vector2d(0, 20);
    if (wild.landmarks[l].point)
      wild.landmarks[l].point = lift_with_depth(wild, wild.landmarks[l].pixel, 1);
  }
  auto wild_fit = fit_neutral(test::face_model(), wild);
  ASSERT_TRUE(wild_fit.ok());
  FitTarget shifted = good;
  for (auto& lm : shifted.landmarks) {
    lm.pixel += Eigen::Vector2d(14, 0);
    if (lm.point) lm.point = lift_with_depth(shifted, lm.pixel, 1);
  }
  auto shifted_fit = fit_neutral(test::face_model(), shifted);
  ASSERT_TRUE(shifted_fit.ok());
  const double few = landmark_disagreement_mm(*wild_fit, wild);
  const double all = landmark_disagreement_mm(*shifted_fit, shifted);
  std::printf(
      "landmark disagreement: right %.2f mm, 6 wild points %.2f mm, all 14 px off %.2f mm\n", right,
      few, all);
  EXPECT_LT(right, 2.5);
  EXPECT_TRUE(fit_passes_qa(*fit, good));
  EXPECT_TRUE(fit_passes_qa(*wild_fit, wild));
  EXPECT_GT(all, 8.0);
  EXPECT_FALSE(fit_passes_qa(*shifted_fit, shifted));
}

TEST(Fitting, RigidAlignmentIgnoresTheNeck) {
  // The rigid subset's neck is neither shaped by the neutral fit (it lies outside the face
  // region) nor still when the jaw opens: a mesh whose neck is 3 mm off the depth (inside the
  // ICP's 4 mm gate) must get the pose the same mesh with a true neck gets. With the neck in
  // the ICP, eval fit's subject 1 mouth_stretch took a 2.24 mm vertex error (1.14 mm without).
  const FaceModel& model = test::face_model();
  const auto truth = face(random_identity(5));
  const RigidPose pose = truth_pose(truth, 4.0);
  const FitTarget target = render_target(truth, pose);
  std::vector<float> mesh = truth;
  const float chin = truth[3 * model.landmark_vertices[8] + 1];
  int moved = 0;
  for (int v = 0; v < model.vertex_count; ++v)
    if (truth[3 * v + 1] < chin) {
      mesh[3 * v + 2] += 3.0f;  // along the face's depth
      ++moved;
    }
  ASSERT_GT(moved, 100);
  // Started 2 deg off, as a transferred expression is from the neutral's pose.
  RigidPose start = pose;
  start.rotation = pose.rotation * Eigen::Quaterniond(Eigen::AngleAxisd(2.0 * M_PI / 180,
                                                                        Eigen::Vector3d::UnitX()));
  // The face vertices an expression leaves still, as fit_expression passes them.
  const std::span<const std::uint32_t> still = model.fitting_vertices;
  auto true_neck = align_rigid(model, target, truth, 8, start, {}, still);
  auto off_neck = align_rigid(model, target, mesh, 8, start, {}, still);
  ASSERT_TRUE(true_neck.ok()) << true_neck.error().message;
  ASSERT_TRUE(off_neck.ok()) << off_neck.error().message;
  const double deg = pose_angle_deg(*off_neck, *true_neck);
  const double mm =
      mean_vertex_distance(truth, *off_neck, truth, *true_neck, model.fitting_vertices);
  std::printf("rigid alignment, neck 3 mm off vs true: %.4f deg, face moved %.4f mm\n", deg, mm);
  EXPECT_LT(deg, 0.01);
  EXPECT_LT(mm, 0.01);
}

TEST(Fitting, RigidAlignmentMatchesTheFaceNotTheLandmarks) {
  // An open mouth's lip and jaw points, and raised brows, sit far from where the transferred
  // start puts them. The model's rigid subset is mostly the back of the head, which a frontal
  // capture's depth does not show: aligned on it, the pose is the landmarks' alone. Given the
  // face vertices the expression leaves still, depth decides, from either start.
  const FaceModel& model = test::face_model();
  const auto truth = face(random_identity(7));
  const RigidPose pose = truth_pose(truth, 4.0);
  FitTarget target = render_target(truth, pose);
  for (int l = 17; l < 68; ++l) {
    auto& lm = target.landmarks[static_cast<std::size_t>(l)];
    if ((l < 27 || l > 47) && lm.point) *lm.point += Eigen::Vector3d(25.0, -30.0, 10.0);
  }
  const std::span<const std::uint32_t> still = model.fitting_vertices;
  auto rigid_subset = align_rigid(model, target, truth, 8);
  auto face_all = align_rigid(model, target, truth, 8, std::nullopt, {}, still);
  auto face_two = align_rigid(model, target, truth, 8, std::nullopt, kRigidFaceLandmarks, still);
  ASSERT_TRUE(rigid_subset.ok()) << rigid_subset.error().message;
  ASSERT_TRUE(face_all.ok()) << face_all.error().message;
  ASSERT_TRUE(face_two.ok()) << face_two.error().message;
  auto err = [&](const RigidPose& p) {
    return mean_vertex_distance(truth, p, truth, pose, model.fitting_vertices);
  };
  std::printf(
      "rigid alignment, mouth and brow points 40 mm off: rigid subset %.3f mm, face "
      "vertices %.3f mm, face vertices from two starts %.3f mm\n",
      err(*rigid_subset), err(*face_all), err(*face_two));
  EXPECT_GT(err(*rigid_subset), 5.0);
  EXPECT_LT(err(*face_all), 0.6);
  EXPECT_LT(err(*face_two), 0.6);
}

TEST(Fitting, WrongLandmarkHasBoundedEffectAndCorrectionRefits) {
  const auto truth = face(random_identity(13));
  const RigidPose pose = truth_pose(truth);
  FitTarget target = render_target(truth, pose);
  auto base = fit_neutral(test::face_model(), target);
  ASSERT_TRUE(base.ok());
  // The operator drags the nose tip (30) 20 px off: the fit moves, but boundedly.
  const Eigen::Vector2d moved = target.landmarks[30].pixel + Eigen::Vector2d(20, 0);
  const LandmarkCorrection corr{30, moved, false};
  ASSERT_TRUE(apply_corrections(target, std::span(&corr, 1)).ok());
  EXPECT_TRUE(target.landmarks[30].point.has_value());
  auto refit = fit_neutral(test::face_model(), target, {}, &*base);
  ASSERT_TRUE(refit.ok());
  const double change =
      mean_vertex_distance(refit->vertices, refit->camera_from_model, base->vertices,
                           base->camera_from_model, test::face_model().fitting_vertices);
  const double err = mean_vertex_distance(refit->vertices, refit->camera_from_model, truth, pose,
                                          test::face_model().fitting_vertices);
  const Eigen::Vector3d nose_before = base->camera_vertex(test::face_model().landmark_vertices[30]);
  const Eigen::Vector3d nose_after = refit->camera_vertex(test::face_model().landmark_vertices[30]);
  std::printf("20 px wrong nose tip: mean change %.3f mm, error %.3f mm, nose moved %.2f mm\n",
              change, err, (nose_after - nose_before).norm());
  EXPECT_GT((nose_after - nose_before).norm(), 0.2);  // the correction is honoured
  EXPECT_LT(change, 1.0);  // stated bound: mean face change < 1 mm for one 20 px error
  EXPECT_LT(err, 1.5);
  // Bad corrections are errors.
  const LandmarkCorrection bad{68, moved, false};
  EXPECT_FALSE(apply_corrections(target, std::span(&bad, 1)).ok());
}

TEST(Fitting, BadInputGivesClearErrors) {
  FitTarget empty;
  empty.intrinsics = kinect();
  auto r = prepare_fit_target(empty);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("depth map is empty"), std::string::npos);
  EXPECT_FALSE(fit_neutral(test::face_model(), empty).ok());

  const auto truth = face({});
  FitTarget no_face = render_target(truth, truth_pose(truth));
  for (auto& lm : no_face.landmarks) lm = FitLandmark{};
  r = prepare_fit_target(no_face);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("no face landmarks"), std::string::npos);

  // Depth missing in the face box: landmarks exist but have no depth.
  FitTarget no_depth = render_target(truth, truth_pose(truth));
  std::fill(no_depth.depth_mm.pixels.begin(), no_depth.depth_mm.pixels.end(), 0.0f);
  for (auto& lm : no_depth.landmarks) lm.point.reset();
  no_depth.normals = {};
  r = prepare_fit_target(no_depth);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("depth"), std::string::npos) << r.error().message;
  auto f = fit_neutral(test::face_model(), no_depth);
  ASSERT_FALSE(f.ok());
}

// Issue 35: a fit whose face had no depth sample within its gate reported "RMS nan mm". The
// landmarks keep their 3D points but the depth lies 300 mm behind them (e.g. a wall seen
// through a misregistered face): the fit now fails and says what to do.
TEST(Fitting, NoDepthSampleInTheGateIsAClearErrorNotNaN) {
  const auto truth = face({});
  FitTarget far = render_target(truth, truth_pose(truth));
  int moved = 0;
  for (float& z : far.depth_mm.pixels)
    if (z > 0) z += 300.0f, ++moved;
  far.normals = {};
  ASSERT_TRUE(prepare_fit_target(far).ok());  // 3D landmarks are there: the fit runs
  ASSERT_GT(moved, 10000);
  for (const bool refine : {true, false}) {
    NeutralFitOptions o;
    o.refine = refine;
    auto f = fit_neutral(test::face_model(), far, o);
    ASSERT_FALSE(f.ok()) << "RMS " << f->rms_to_depth_mm << " mm over " << f->depth_correspondences
                         << " correspondences";
    const std::string& why = f.error().message;
    std::printf("refine %d: %s\n", refine, why.c_str());
    EXPECT_NE(why.find("no depth sample lies within 10 mm of the fitted face"), std::string::npos)
        << why;
    EXPECT_NE(why.find("record again"), std::string::npos) << why;
    EXPECT_EQ(why.find("nan"), std::string::npos) << why;
  }
  // The same face with its depth in place still fits.
  const FitTarget near = render_target(truth, truth_pose(truth));
  auto ok = fit_neutral(test::face_model(), near);
  ASSERT_TRUE(ok.ok()) << ok.error().message;
  EXPECT_GT(ok->depth_correspondences, 3000);
}

// A ray-cast view comes with its own normals, one-sided on its rims; the fit keeps them only
// inside one surface, so the rims of holes and the silhouette never enter Epos.
TEST(Fitting, GivenNormalsAreClearedOnRimsOfHolesAndSilhouettes) {
  const auto truth = face({});
  FitTarget t = render_target(truth, truth_pose(truth));
  const Eigen::Vector3d nose = t.landmarks[30].point.value();
  const Eigen::Vector2d nose_px = t.intrinsics.project(nose);
  const int hx = static_cast<int>(nose_px.x()) + 30, hy = static_cast<int>(nose_px.y());
  for (int y = hy; y < hy + 10; ++y)
    for (int x = hx; x < hx + 10; ++x) t.depth_mm.at(x, y) = 0.0f;  // a hole on the cheek
  ASSERT_GT(t.depth_mm.at(hx - 5, hy + 5), 0.0f);
  const Eigen::Vector3f marker(0.0f, 0.0f, -1.0f);
  std::fill(t.normals.pixels.begin(), t.normals.pixels.end(), marker);
  ASSERT_TRUE(prepare_fit_target(t).ok());
  EXPECT_EQ(t.normals.at(hx + 5, hy + 5), Eigen::Vector3f::Zero());  // in the hole
  EXPECT_EQ(t.normals.at(hx - 1, hy + 5), Eigen::Vector3f::Zero());  // its rim
  EXPECT_EQ(t.normals.at(hx + 10, hy + 5), Eigen::Vector3f::Zero());
  EXPECT_EQ(t.normals.at(hx + 5, hy - 1), Eigen::Vector3f::Zero());
  EXPECT_EQ(t.normals.at(hx - 5, hy + 5), marker);         // the surface beside it keeps its normal
  EXPECT_EQ(t.normals.at(2, 2), Eigen::Vector3f::Zero());  // background
  int kept = 0, silhouette_kept = 0;
  for (int y = 1; y + 1 < t.depth_mm.height; ++y)
    for (int x = 1; x + 1 < t.depth_mm.width; ++x) {
      if (t.normals.at(x, y) != marker) continue;
      ++kept;
      if (t.depth_mm.at(x - 1, y) <= 0.0f || t.depth_mm.at(x + 1, y) <= 0.0f) ++silhouette_kept;
    }
  EXPECT_GT(kept, 20000);
  EXPECT_EQ(silhouette_kept, 0);
}

}  // namespace
}  // namespace fb

namespace fb {
namespace {

// Hair over the forehead on a Kinect: the depth there sits several mm in front of the skin and
// scatters. With the take's confidence map (low there) the refinement holds the forehead where
// its start put it; without it, it chases the hair.
TEST(Fitting, UnreliableDepthIsHeldByTheModel) {
  const auto truth = face(random_identity(4));
  const RigidPose pose = truth_pose(truth, 4.0);
  FitTarget target = render_target(truth, pose, 0.5);
  const double brow_y = top_of_brows_px(target);
  const int hair_below = static_cast<int>(brow_y) - 12;  // rows above this are "hair"
  std::mt19937 rng(11);
  std::normal_distribution<float> scatter(0.0f, 2.0f);
  target.confidence.resize(640, 480);
  for (int y = 0; y < 480; ++y)
    for (int x = 0; x < 640; ++x) {
      float& z = target.depth_mm.at(x, y);
      const bool hair = y < hair_below && z > 0;
      if (hair) z -= 6.0f + scatter(rng);
      target.confidence.at(x, y) = hair ? 0.05f : 1.0f;
    }
  target.normals = {};
  ASSERT_TRUE(prepare_fit_target(target).ok());
  FitTarget blind = target;
  blind.confidence = {};
  // The forehead vertices under the hair.
  std::vector<std::uint32_t> forehead;
  for (std::uint32_t v : test::face_model().fitting_vertices) {
    const Eigen::Vector3d p = pose.apply({truth[3 * v], truth[3 * v + 1], truth[3 * v + 2]});
    if (target.intrinsics.project(p).y() < hair_below - 3) forehead.push_back(v);
  }
  ASSERT_GT(forehead.size(), 200u);
  // The refinement from a start 1 mm off the true face along its normals.
  std::vector<float> start = truth;
  {
    const auto normals = fitting_detail::vertex_normals(fitting_detail::to_points(truth),
                                                        test::face_model().triangles);
    for (Eigen::Index v = 0; v < normals.rows(); ++v)
      for (int a = 0; a < 3; ++a) start[3 * v + a] += static_cast<float>(normals(v, a));
  }
  auto with = refine_fit(test::face_model(), target, start, pose);
  auto without = refine_fit(test::face_model(), blind, start, pose);
  ASSERT_TRUE(with.ok()) << with.error().message;
  ASSERT_TRUE(without.ok()) << without.error().message;
  const double e_with =
      mean_vertex_distance(with->vertices, with->camera_from_model, truth, pose, forehead);
  const double e_without =
      mean_vertex_distance(without->vertices, without->camera_from_model, truth, pose, forehead);
  const double all_with = mean_vertex_distance(with->vertices, with->camera_from_model, truth, pose,
                                               test::face_model().fitting_vertices);
  std::printf(
      "forehead under hair: %.2f mm with the confidence map, %.2f mm without; face %.2f mm\n",
      e_with, e_without, all_with);
  EXPECT_LT(e_with, 0.5 * e_without);
  EXPECT_LT(e_with, 1.5);
  EXPECT_LT(all_with, 1.0);
}

}  // namespace
}  // namespace fb

namespace fb {
namespace {

// A hair cap over the forehead, 8 mm in front of the skin with scatter, that the colour marks as
// not skin (FitTarget::skin): the whole fit (PCA step and refinement) takes that depth as a
// bound, so the forehead under it stays near the skin; without the skin map it follows the hair.
TEST(Fitting, HairDepthIsABoundNotTheSurface) {
  const auto truth = face(random_identity(5));
  const RigidPose pose = truth_pose(truth, 3.0);
  FitTarget target = render_target(truth, pose, 0.5);
  const double brow_y = top_of_brows_px(target);
  const int hair_below = static_cast<int>(brow_y) - 14;
  std::mt19937 rng(5);
  std::normal_distribution<float> scatter(0.0f, 2.0f);
  target.skin.resize(640, 480);
  for (int y = 0; y < 480; ++y)
    for (int x = 0; x < 640; ++x) {
      float& z = target.depth_mm.at(x, y);
      const bool hair = y < hair_below && z > 0;
      if (hair) z -= 8.0f + scatter(rng);
      target.skin.at(x, y) = hair ? 0.0f : 1.0f;
    }
  target.normals = {};
  ASSERT_TRUE(prepare_fit_target(target).ok());
  FitTarget blind = target;
  blind.skin = {};
  std::vector<std::uint32_t> forehead;
  for (std::uint32_t v : test::face_model().fitting_vertices) {
    const Eigen::Vector3d p = pose.apply({truth[3 * v], truth[3 * v + 1], truth[3 * v + 2]});
    if (target.intrinsics.project(p).y() < hair_below - 3) forehead.push_back(v);
  }
  ASSERT_GT(forehead.size(), 200u);
  auto with = fit_neutral(test::face_model(), target);
  auto without = fit_neutral(test::face_model(), blind);
  ASSERT_TRUE(with.ok()) << with.error().message;
  ASSERT_TRUE(without.ok()) << without.error().message;
  auto error = [&](const FitResult& f, std::span<const std::uint32_t> subset) {
    return mean_vertex_distance(f.vertices, f.camera_from_model, truth, pose, subset);
  };
  const double e_with = error(*with, forehead), e_without = error(*without, forehead);
  const double all_with = error(*with, test::face_model().fitting_vertices);
  const double all_without = error(*without, test::face_model().fitting_vertices);
  std::printf("forehead under hair: %.2f mm with the skin map, %.2f mm without; face %.2f / %.2f\n",
              e_with, e_without, all_with, all_without);
  EXPECT_LT(e_with, 0.65 * e_without);  // measured 2.60 vs 5.11: the weak pull (hair_weight)
  EXPECT_LT(all_with, all_without);
}

// At the hairline fused depth ramps up to the hair's surface, so the depth's normals there face
// down the forehead. A hair sample pulls along the face's own normal: along the ramp's, it slid
// the skin below down the face (the hair part of `eval fit`, docs/tuning.md).
TEST(Fitting, HairPullsAlongTheFacesNormalNotTheHairlinesRamp) {
  const auto truth = face(random_identity(7));
  const RigidPose pose = truth_pose(truth, 0.0);
  FitTarget target = render_target(truth, pose, 0.5);
  const double brow_y = top_of_brows_px(target);
  const int hairline = static_cast<int>(brow_y) - 30, ramp_px = 5;
  std::mt19937 rng(7);
  std::normal_distribution<float> scatter(0.0f, 1.0f);
  target.skin.resize(640, 480);
  for (int y = 0; y < 480; ++y)
    for (int x = 0; x < 640; ++x) {
      float& z = target.depth_mm.at(x, y);
      const float hair = std::clamp(static_cast<float>(hairline - y) / ramp_px, 0.0f, 1.0f);
      if (z > 0 && hair > 0) z -= 8.0f * hair + scatter(rng);
      target.skin.at(x, y) = hair > 0 ? 0.0f : 1.0f;
    }
  target.normals = {};
  ASSERT_TRUE(prepare_fit_target(target).ok());
  // The skin below the hairline: how far its vertices slid up or down the face (image y).
  std::vector<std::uint32_t> skin;
  for (std::uint32_t v : test::face_model().fitting_vertices) {
    const Eigen::Vector3d p = pose.apply({truth[3 * v], truth[3 * v + 1], truth[3 * v + 2]});
    const double y = target.intrinsics.project(p).y();
    if (y > hairline + 3 && y < brow_y) skin.push_back(v);
  }
  ASSERT_GT(skin.size(), 150u);
  auto fit = fit_neutral(test::face_model(), target);
  ASSERT_TRUE(fit.ok()) << fit.error().message;
  double slide = 0;
  for (std::uint32_t v : skin) {
    const Eigen::Vector3d p = pose.apply({truth[3 * v], truth[3 * v + 1], truth[3 * v + 2]});
    slide += fit->camera_vertex(static_cast<int>(v)).y() - p.y();
  }
  slide /= static_cast<double>(skin.size());
  const double forehead =
      mean_vertex_distance(fit->vertices, fit->camera_from_model, truth, pose, skin);
  std::printf("forehead below the hairline: slid %.2f mm down the face, error %.2f mm\n", slide,
              forehead);
  EXPECT_LT(std::abs(slide), 0.5);
  EXPECT_LT(forehead, 1.0);
}

// Hair the skin map missed (a fringe over one brow, 7 mm in front of the skin, read as skin):
// the PCA step's Cauchy weight keeps it from bending the whole face's identity towards it.
TEST(Fitting, HairTheSkinMapMissedDoesNotBendTheWholeFace) {
  const auto truth = face(random_identity(8));
  const RigidPose pose = truth_pose(truth, 2.0);
  FitTarget target = render_target(truth, pose, 0.5);
  const double brow_y = top_of_brows_px(target);
  const double nose_x = target.landmarks[30].pixel.x();
  const int top = static_cast<int>(brow_y) - 45, bottom = static_cast<int>(brow_y) + 5;
  auto in_fringe = [&](double x, double y) { return y >= top && y <= bottom && x < nose_x; };
  std::mt19937 rng(8);
  std::normal_distribution<float> scatter(0.0f, 1.0f);
  for (int y = 0; y < 480; ++y)
    for (int x = 0; x < 640; ++x) {
      float& z = target.depth_mm.at(x, y);
      if (z > 0 && in_fringe(x, y)) z -= 7.0f + scatter(rng);
    }
  target.normals = {};
  ASSERT_TRUE(prepare_fit_target(target).ok());
  const FitTarget clean = render_target(truth, pose, 0.5);
  // The face away from the fringe (10 px clear of it).
  std::vector<std::uint32_t> elsewhere;
  for (std::uint32_t v : test::face_model().fitting_vertices) {
    const Eigen::Vector2d px =
        target.intrinsics.project(pose.apply({truth[3 * v], truth[3 * v + 1], truth[3 * v + 2]}));
    if (px.y() > bottom + 10 || px.y() < top - 10 || px.x() > nose_x + 10) elsewhere.push_back(v);
  }
  ASSERT_GT(elsewhere.size(), 3000u);
  // The Cauchy weight alone (the offsets, which also keep a fringe local, off).
  NeutralFitOptions cauchy;
  cauchy.offset_amplitude_mm = 0.0;
  NeutralFitOptions plain = cauchy;
  plain.robust_scale_mm = 0.0;
  auto without_fringe = fit_neutral(test::face_model(), clean, cauchy);
  ASSERT_TRUE(without_fringe.ok()) << without_fringe.error().message;
  auto robust = fit_neutral(test::face_model(), target, cauchy);
  auto squares = fit_neutral(test::face_model(), target, plain);
  ASSERT_TRUE(robust.ok()) << robust.error().message;
  ASSERT_TRUE(squares.ok()) << squares.error().message;
  auto error = [&](const FitResult& f) {
    return mean_vertex_distance(f.initial_vertices, f.camera_from_model, truth, pose, elsewhere);
  };
  const double e_robust = error(*robust), e_squares = error(*squares);
  const double e_clean = error(*without_fringe);
  std::printf(
      "PCA step away from the fringe: %.3f mm with the Cauchy weight, %.3f mm without; "
      "%.3f mm with no fringe\n",
      e_robust, e_squares, e_clean);
  EXPECT_LT(e_robust, 0.8 * e_squares);
  // Measured 0.765 / 1.205 / 0.261: the weight takes out about half of what the fringe did.
  EXPECT_LT(e_robust - e_clean, 0.65 * (e_squares - e_clean));
}

// A detector's jaw line on a beard follows the beard's outline: contour points whose
// surroundings are not skin are dropped; the others and the interior points stay.
TEST(Fitting, ContourPointsOnABeardAreDropped) {
  const auto truth = face(random_identity(6));
  const RigidPose pose = truth_pose(truth, 0.0);
  FitTarget target = render_target(truth, pose, 0.0);
  target.skin.resize(640, 480);
  const double mouth_y = target.landmarks[57].pixel.y();
  for (int y = 0; y < 480; ++y)
    for (int x = 0; x < 640; ++x) target.skin.at(x, y) = y > mouth_y ? 0.0f : 1.0f;
  std::array<double, 17> contour_y{};
  for (int l = 0; l <= 16; ++l) contour_y[l] = target.landmarks[l].pixel.y();
  ASSERT_TRUE(prepare_fit_target(target).ok());
  int dropped = 0;
  for (int l = 0; l <= 16; ++l)
    if (contour_y[l] > mouth_y + 6) {
      EXPECT_FALSE(target.landmarks[l].valid) << "contour point " << l;
      ++dropped;
    }
  EXPECT_GE(dropped, 5);
  EXPECT_TRUE(target.landmarks[0].valid);
  EXPECT_TRUE(target.landmarks[16].valid);
  for (int l = 17; l < 68; ++l) EXPECT_TRUE(target.landmarks[l].valid) << l;
}

}  // namespace
}  // namespace fb
