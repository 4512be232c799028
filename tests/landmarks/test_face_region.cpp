// The capture's face box (issue 35, item 1): from dlib's face on the colour image, through the
// registration, grown to the whole forehead and chin by the face model's proportions, placed at
// the face's depth and following the fused pose. Scored against the synthetic camera's truth.
#include "algo/landmarks/face_region_box.hpp"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "algo/fusion/face_fusion.hpp"
#include "sim/camera/synthetic_camera.hpp"
#include "tests/common/test_face_model.hpp"

namespace fb {
namespace {

using std::chrono::milliseconds;

constexpr const char* kPredictor = "/usr/share/dlib/shape_predictor_68_face_landmarks.dat";

std::optional<LandmarkDetector> detector() {
  std::ifstream in(kPredictor, std::ios::binary);
  auto d = LandmarkDetector::create(in);
  EXPECT_TRUE(d.ok()) << (d.ok() ? "" : d.error().message);
  if (!d) return std::nullopt;
  return std::move(*d);
}

std::unique_ptr<SyntheticCamera> open_uri(const std::string& arguments) {
  auto options = parse_synthetic_options(arguments, test::face_model());
  EXPECT_TRUE(options.ok()) << (options.ok() ? "" : options.error().message);
  if (!options) return nullptr;
  auto camera = make_synthetic_camera(test::face_model(), *options);
  EXPECT_TRUE(camera.ok()) << (camera.ok() ? "" : camera.error().message);
  if (!camera) return nullptr;
  EXPECT_TRUE((*camera)->start().ok());
  return std::move(*camera);
}

// The face region's vertices of frame `truth` from the top of the forehead down to the chin
// landmark (the neck below it is not face), projected into the depth image; only those the
// camera sees (their depth is the rendered surface's).
std::vector<Eigen::Vector2d> face_region_pixels(SyntheticCamera& camera, const FrameTruth& truth) {
  const FaceModel& model = test::face_model();
  const auto rest = camera.model_vertices();
  const PinholeIntrinsics& k = camera.info().depth_intrinsics;
  const double chin_y = truth.landmarks_depth_px[8].y();
  std::vector<Eigen::Vector2d> out;
  for (int v = 0; v < model.face_vertex_count; ++v) {
    const Eigen::Vector3d p = truth.camera_from_model.apply(rest[v].cast<double>());
    const Eigen::Vector2d px(k.fx * p.x() / p.z() + k.cx, k.fy * p.y() / p.z() + k.cy);
    const int x = static_cast<int>(px.x()), y = static_cast<int>(px.y());
    if (px.y() > chin_y + 1.0 || !truth.noiseless_depth_mm.contains(x, y)) continue;
    const float z = truth.noiseless_depth_mm.at(x, y);
    if (z <= 0.0f || std::abs(z - p.z()) > 5.0) continue;  // hidden (or the silhouette)
    out.push_back(px);
  }
  return out;
}

double fraction_inside(const FaceBox& box, const std::vector<Eigen::Vector2d>& px) {
  int in = 0;
  for (const auto& p : px)
    in +=
        box.rect.contains(static_cast<int>(std::floor(p.x())), static_cast<int>(std::floor(p.y())));
  return px.empty() ? 0.0 : static_cast<double>(in) / static_cast<double>(px.size());
}

TEST(FaceRegion, ProportionsComeFromTheModelsForeheadAndChin) {
  const FaceProportions p = face_proportions(test::face_model());
  std::printf("face proportions: above %.3f below %.3f sides %.3f\n", p.above, p.below, p.sides);
  // The forehead reaches well above the brows (the highest landmarks); the chin's front ends
  // a little below the chin landmark; the defaults (used where no model is loaded, as in eval
  // fusion) are these figures.
  EXPECT_GT(p.above, 0.3);
  EXPECT_LT(p.below, 0.15);
  const FaceProportions d;
  EXPECT_NEAR(p.above, d.above, 0.02);
  EXPECT_NEAR(p.below, d.below, 0.02);
  EXPECT_NEAR(p.sides, d.sides, 0.02);
}

TEST(FaceRegion, TooFewLandmarksIsAClearError) {
  std::array<FitLandmark, kFitLandmarkCount> none{};
  auto box = face_box_from_landmarks(none, {}, 640, 480);
  ASSERT_FALSE(box.ok());
  EXPECT_NE(box.error().message.find("landmarks"), std::string::npos) << box.error().message;
}

// A face high and off-centre with the chest and a desk nearer than it (what the fixed kiosk
// rectangle cut: forehead out of the box, the chest taking the volume): the detected box holds
// the whole face region, and fusion follows it through the head turn on every frame.
TEST(FaceRegion, HighOffCentreFaceFusesEveryFrameInItsDetectedBox) {
  if (!std::filesystem::exists(kPredictor)) GTEST_SKIP() << "libdlib-data not installed";
  auto dlib = detector();
  ASSERT_TRUE(dlib);
  constexpr int kFrames = 60;
  auto camera = open_uri("seed=1,motion=headturn,frames=" + std::to_string(kFrames) +
                         ",offset_x=70,offset_y=-95,torso=on,desk=on");
  ASSERT_TRUE(camera);
  RgbdFrame frame;
  std::vector<DepthImage> depth;
  ColorImage first_color;
  FrameTruth first_truth;
  for (int i = 0; i < kFrames; ++i) {
    auto st = camera->next_frame(frame, milliseconds(0));
    ASSERT_TRUE(st.ok() && *st == FrameStatus::kFrame);
    depth.push_back(frame.depth_mm);
    if (i == 0) {
      first_color = frame.color;
      first_truth = *camera->truth();
    }
  }
  const CameraInfo& info = camera->info();
  auto region =
      detect_face_region(*dlib, first_color, depth.front(), KinectRegistration(info.calibration),
                         face_proportions(test::face_model()));
  ASSERT_TRUE(region.ok()) << region.error().message;
  const FaceBox& box = region->box;
  // Its forehead, brows and chin: the face region's vertices and the brow (19, 24) and chin (8)
  // landmarks in the depth image.
  const auto face_px = face_region_pixels(*camera, first_truth);
  const double inside = fraction_inside(box, face_px);
  const FaceBox kiosk = default_face_box(info.width, info.height);
  const double kiosk_inside = fraction_inside(kiosk, face_px);
  std::printf(
      "detected box %d,%d %dx%d (face depth %.0f mm): %.1f %% of the face region inside "
      "(the kiosk rectangle: %.1f %%)\n",
      box.rect.x0, box.rect.y0, box.rect.width(), box.rect.height(), box.face_depth_mm,
      100 * inside, 100 * kiosk_inside);
  EXPECT_GT(inside, 0.97);
  EXPECT_LT(kiosk_inside, 0.8) << "the scene no longer puts the face outside the kiosk box";
  for (int l : {8, 19, 24}) {
    const Eigen::Vector2d& p = first_truth.landmarks_depth_px[static_cast<std::size_t>(l)];
    EXPECT_TRUE(box.rect.contains(static_cast<int>(p.x()), static_cast<int>(p.y()))) << l;
  }
  double z = 0;
  for (const auto& p : first_truth.landmarks_3d) z += p.z() / 68.0;
  EXPECT_NEAR(box.face_depth_mm, z, 25.0);

  // Fusion in that box follows the face over the take; in the fixed box it loses it.
  auto fuse = [&](const FaceBox& b, bool follow, FaceFusion& fusion) {
    FusionOptions o;
    o.box_follows_face = follow;
    EXPECT_TRUE(fusion.reset(info.depth_intrinsics, b, o).ok());
    int fused = 0;
    for (const DepthImage& d : depth) {
      const FrameReport r = fusion.process(d);
      fused += r.fused;
      if (std::getenv("FB_FUSION_VERBOSE"))
        std::printf("%s %s inliers %d rms %.2f box %d,%d %dx%d\n", to_string(r.state),
                    r.loss_reason, r.inliers, r.rms_mm, fusion.face_box().rect.x0,
                    fusion.face_box().rect.y0, fusion.face_box().rect.width(),
                    fusion.face_box().rect.height());
    }
    return fused;
  };
  FaceFusion fusion;
  const int fused = fuse(box, true, fusion);
  FaceFusion fixed;
  const int fused_fixed = fuse(kiosk, false, fixed);
  std::printf("fused %d of %d frames in the detected, following box; %d in the kiosk box\n", fused,
              kFrames, fused_fixed);
  EXPECT_EQ(fused, kFrames);
  EXPECT_LT(fused_fixed, kFrames);
  // The frontal render holds the forehead: fused depth under the forehead's vertices.
  const SurfaceView view = fusion.render(RigidPose{});
  int forehead = 0, forehead_depth = 0;
  const double brow_y =
      std::min(first_truth.landmarks_depth_px[19].y(), first_truth.landmarks_depth_px[24].y());
  for (const auto& p : face_px) {
    const int x = static_cast<int>(p.x()), y = static_cast<int>(p.y());
    if (p.y() > brow_y - 10 || !view.depth_mm.contains(x, y)) continue;
    ++forehead;
    forehead_depth += view.depth_mm.at(x, y) > 0.0f;
  }
  std::printf("forehead vertices with fused depth: %d of %d\n", forehead_depth, forehead);
  ASSERT_GT(forehead, 100);
  EXPECT_GT(static_cast<double>(forehead_depth) / forehead, 0.95);
}

}  // namespace
}  // namespace fb
