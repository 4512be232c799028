#include "sim/camera/synthetic_camera.hpp"

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <new>

#include <gtest/gtest.h>

#include "storage/asset_files.hpp"
#include "tests/common/allocation_counter.hpp"
#include "tests/common/test_face_model.hpp"

namespace fb {
namespace {

using std::chrono::milliseconds;

std::unique_ptr<SyntheticCamera> make(const SyntheticOptions& options) {
  auto camera = make_synthetic_camera(test::face_model(), options);
  EXPECT_TRUE(camera.ok()) << (camera.ok() ? "" : camera.error().message);
  if (!camera) return nullptr;
  EXPECT_TRUE((*camera)->start().ok());
  return std::move(*camera);
}

// Face pixels: rendered head closer than the wall, inside the landmark bounding box.
template <class F>
void for_face_pixels(const FrameTruth& truth, double background, F&& f) {
  double x0 = 1e9, x1 = -1e9, y0 = 1e9, y1 = -1e9;
  for (const auto& p : truth.landmarks_depth_px) {
    x0 = std::min(x0, p.x());
    x1 = std::max(x1, p.x());
    y0 = std::min(y0, p.y());
    y1 = std::max(y1, p.y());
  }
  const auto& z = truth.noiseless_depth_mm;
  for (int y = std::max(0, static_cast<int>(y0)); y <= std::min(z.height - 1, static_cast<int>(y1));
       ++y) {
    for (int x = std::max(0, static_cast<int>(x0));
         x <= std::min(z.width - 1, static_cast<int>(x1)); ++x) {
      const float d = z.at(x, y);
      if (d > 0.0f && d < background - 100.0) f(x, y, d);
    }
  }
}

struct FaceStats {
  double mean_abs_error = 0.0;
  double hole_fraction = 0.0;
  long pixels = 0;
};

FaceStats face_stats(double distance, int frames, std::uint64_t seed = 0) {
  SyntheticOptions options;
  options.seed = seed;
  options.motion = SyntheticMotion::kStatic;
  options.distance_mm = distance;
  options.background_mm = distance + 500.0;
  options.frame_count = frames;
  auto camera = make(options);
  RgbdFrame frame;
  double error = 0.0;
  long measured = 0, face = 0, holes = 0;
  while (true) {
    auto status = camera->next_frame(frame, milliseconds(0));
    EXPECT_TRUE(status.ok());
    if (!status.ok() || *status != FrameStatus::kFrame) break;
    for_face_pixels(*camera->truth(), options.background_mm, [&](int x, int y, float d) {
      ++face;
      const auto mm = frame.depth_mm.at(x, y);
      if (mm == 0) {
        ++holes;
        return;
      }
      error += std::abs(mm - d);
      ++measured;
    });
  }
  return {error / std::max(measured, 1L), static_cast<double>(holes) / std::max(face, 1L), face};
}

TEST(SyntheticCamera, UriDefaultsOpenAndStreamEndsAfterFrames) {
  auto camera = open_camera("synthetic:frames=3,seed=5");
  ASSERT_TRUE(camera.ok()) << camera.error().message;
  EXPECT_EQ((*camera)->info().backend, "synthetic");
  EXPECT_EQ((*camera)->info().frame_count, 3);
  EXPECT_EQ((*camera)->info().width, 640);
  ASSERT_TRUE((*camera)->start().ok());
  RgbdFrame frame;
  for (int i = 0; i < 3; ++i) {
    auto status = (*camera)->next_frame(frame, milliseconds(10));
    ASSERT_TRUE(status.ok());
    ASSERT_EQ(*status, FrameStatus::kFrame);
    EXPECT_EQ(frame.index, static_cast<std::uint64_t>(i));
    EXPECT_DOUBLE_EQ(frame.depth_host_time_s, i / 30.0);
    EXPECT_EQ(frame.depth_device_timestamp, static_cast<std::uint32_t>(i * 2'000'000));
    EXPECT_EQ(frame.depth_mm.width, 640);
    EXPECT_EQ(frame.color.height, 480);
    ASSERT_NE(frame_truth(**camera), nullptr);
  }
  auto end = (*camera)->next_frame(frame, milliseconds(10));
  ASSERT_TRUE(end.ok());
  EXPECT_EQ(*end, FrameStatus::kEndOfStream);
}

TEST(SyntheticCamera, BadUrisGiveClearErrors) {
  struct Case {
    const char* uri;
    const char* mentions;
  } cases[] = {
      {"synthetic:colour=red", "accepted"},
      {"synthetic:seed=abc", "seed"},
      {"synthetic:expr=notAnExpression", "jawOpen"},
      {"synthetic:expr=jawOpen:lots", "weight"},
      {"synthetic:motion=spin", "headturn or static"},
      {"synthetic:anim=dance", "expressive or none"},
      {"synthetic:frames=0", "frames"},
      {"synthetic:distance=50", "distance"},
      {"synthetic:noise=maybe", "on or off"},
      {"synthetic:background=700", "behind"},
      {"synthetic:identity=alice", "random or neutral"},
  };
  for (const auto& c : cases) {
    auto camera = open_camera(c.uri);
    ASSERT_FALSE(camera.ok()) << c.uri;
    EXPECT_NE(camera.error().message.find(c.mentions), std::string::npos)
        << c.uri << ": " << camera.error().message;
  }
}

TEST(SyntheticCamera, ExpressionSpecParsesNamesAndWeights) {
  auto weights = parse_expression_spec("jawOpen:0.6+mouthSmile_L", test::face_model());
  ASSERT_TRUE(weights.ok()) << weights.error().message;
  ASSERT_EQ(weights->size(), static_cast<std::size_t>(test::face_model().expression_count));
  EXPECT_FLOAT_EQ((*weights)[test::face_model().expression_index("jawOpen")], 0.6f);
  EXPECT_FLOAT_EQ((*weights)[test::face_model().expression_index("mouthSmile_L")], 1.0f);
  auto neutral = parse_expression_spec("neutral", test::face_model());
  ASSERT_TRUE(neutral.ok());
  for (float w : *neutral) EXPECT_EQ(w, 0.0f);
}

// Guide expressions (data/guide_expressions.json) are accepted by name: `expr=smile` is the
// recipe the kiosk shows, scaled by an optional weight and combinable with shapes.
TEST(SyntheticCamera, ExpressionSpecAcceptsGuideExpressions) {
  auto guide = load_guide_expressions(test::face_model());
  ASSERT_TRUE(guide.ok()) << guide.error().message;
  const int smile = guide->find("smile");
  ASSERT_GE(smile, 0);
  auto recipe =
      guide_weights(guide->expressions[static_cast<std::size_t>(smile)], test::face_model());
  ASSERT_TRUE(recipe.ok());
  auto weights = parse_expression_spec("smile:0.5+jawOpen:0.25", test::face_model(), &*guide);
  ASSERT_TRUE(weights.ok()) << weights.error().message;
  int recipe_shapes = 0;
  const int jaw = test::face_model().expression_index("jawOpen");
  for (std::size_t j = 0; j < weights->size(); ++j) {
    const float expected = 0.5f * (*recipe)[j] + (static_cast<int>(j) == jaw ? 0.25f : 0.0f);
    EXPECT_FLOAT_EQ((*weights)[j], expected) << test::face_model().expression_names[j];
    recipe_shapes += (*recipe)[j] > 0.0f;
  }
  EXPECT_GE(recipe_shapes, 2);  // a smile is more than one shape

  auto unknown = parse_expression_spec("smiel", test::face_model(), &*guide);
  ASSERT_FALSE(unknown.ok());
  EXPECT_NE(unknown.error().message.find("guide expressions: neutral"), std::string::npos)
      << unknown.error().message;

  // Through the URI, as a user types it; the truth carries the recipe.
  auto camera = open_camera("synthetic:seed=3,expr=smile,frames=1");
  ASSERT_TRUE(camera.ok()) << camera.error().message;
  ASSERT_TRUE((*camera)->start().ok());
  RgbdFrame frame;
  ASSERT_EQ(*(*camera)->next_frame(frame, milliseconds(0)), FrameStatus::kFrame);
  const FrameTruth* truth = frame_truth(**camera);
  ASSERT_NE(truth, nullptr);
  for (std::size_t j = 0; j < recipe->size(); ++j) {
    EXPECT_FLOAT_EQ(truth->expression_weights[j], (*recipe)[j]);
  }
}

TEST(SyntheticCamera, SameSeedIsBitIdenticalOtherSeedDiffers) {
  auto render = [](std::uint64_t seed, RgbdFrame& frame) {
    SyntheticOptions options;
    options.seed = seed;
    options.frame_count = 6;
    auto camera = make(options);
    for (int i = 0; i < 6; ++i)
      ASSERT_EQ(*camera->next_frame(frame, milliseconds(0)), FrameStatus::kFrame);
  };
  RgbdFrame a, b, c;
  render(3, a);
  render(3, b);
  render(4, c);
  EXPECT_EQ(a.raw_disparity.pixels, b.raw_disparity.pixels);
  EXPECT_EQ(a.depth_mm.pixels, b.depth_mm.pixels);
  EXPECT_TRUE(std::equal(a.color.pixels.begin(), a.color.pixels.end(), b.color.pixels.begin(),
                         [](Rgb8 p, Rgb8 q) { return p.r == q.r && p.g == q.g && p.b == q.b; }));
  EXPECT_NE(a.raw_disparity.pixels, c.raw_disparity.pixels);
}

TEST(SyntheticCamera, TruthIsConsistentWithRenderedDepth) {
  SyntheticOptions options;
  options.motion = SyntheticMotion::kStatic;
  options.sensor.depth_noise = false;
  options.frame_count = 1;
  auto camera = make(options);
  RgbdFrame frame;
  ASSERT_EQ(*camera->next_frame(frame, milliseconds(0)), FrameStatus::kFrame);
  const FrameTruth& truth = *camera->truth();
  ASSERT_EQ(truth.landmarks_3d.size(), 68u);
  EXPECT_EQ(truth.identity_coeffs.size(),
            static_cast<std::size_t>(test::face_model().identity_count));
  EXPECT_EQ(truth.expression_weights.size(),
            static_cast<std::size_t>(test::face_model().expression_count));

  // Landmark centroid sits at (0, 0, 700) in the rest pose.
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const auto& p : truth.landmarks_3d) centroid += p;
  centroid /= 68.0;
  EXPECT_NEAR(centroid.x(), 0.0, 1e-3);
  EXPECT_NEAR(centroid.y(), 0.0, 1e-3);
  EXPECT_NEAR(centroid.z(), 700.0, 1e-3);
  // The face looks at the camera: nose tip (30) nearer than the eye corners, brows above
  // the chin (y down), subject's left eye (45) on the image right.
  EXPECT_LT(truth.landmarks_3d[30].z(), truth.landmarks_3d[36].z());
  EXPECT_LT(truth.landmarks_3d[19].y(), truth.landmarks_3d[8].y());
  EXPECT_GT(truth.landmarks_depth_px[45].x(), truth.landmarks_depth_px[36].x());

  // Frontal interior landmarks (brows, nose, eyes, mouth): the noiseless depth at the 2D
  // position matches the 3D z (the landmark is a mesh vertex, so within a facet's curvature).
  const auto& k = camera->info().depth_intrinsics;
  int checked = 0;
  for (int l = 17; l < 68; ++l) {
    const Eigen::Vector2d px = truth.landmarks_depth_px[l];
    EXPECT_NEAR((k.project(truth.landmarks_3d[l]) - px).norm(), 0.0, 1e-9);
    const int x = static_cast<int>(std::lround(px.x())), y = static_cast<int>(std::lround(px.y()));
    const float d = truth.noiseless_depth_mm.at(x, y);
    if (l >= 60) continue;  // inner lip points border the mouth cap
    // Eyelid points sit on the rim of the (flat, slightly recessed) eye cap, so the rounded
    // pixel may see the cap a few mm behind.
    const double tolerance = (l >= 36 && l < 48) ? 6.0 : 3.0;
    EXPECT_NEAR(d, truth.landmarks_3d[l].z(), tolerance) << "landmark " << l;
    ++checked;
  }
  EXPECT_GT(checked, 30);
  // Colour landmarks land inside the colour image, near the depth positions (the cameras are
  // 2.5 cm apart: tens of pixels at most).
  for (int l = 0; l < 68; ++l) {
    const auto& c = truth.landmarks_color_px[l];
    ASSERT_TRUE(std::isfinite(c.x()) && std::isfinite(c.y()));
    EXPECT_LT((c - truth.landmarks_depth_px[l]).norm(), 60.0);
  }
  // With noise off, measured depth is the quantised noiseless depth.
  const KinectRegistration registration(camera->info().calibration);
  long measured = 0;
  for (std::size_t i = 0; i < frame.depth_mm.pixels.size(); ++i) {
    if (frame.depth_mm.pixels[i] == 0) continue;
    ++measured;
    const auto mm = static_cast<std::uint16_t>(std::lround(truth.noiseless_depth_mm.pixels[i]));
    ASSERT_EQ(frame.depth_mm.pixels[i], registration.raw_to_mm(registration.mm_to_raw(mm)));
  }
  EXPECT_GT(measured, 200000);
}

// A personal expression basis replaces the generic one: twice the generic shapes at weight 0.5
// render the generic face at weight 1, and the truth landmarks follow the personal shapes.
TEST(SyntheticCamera, PersonalExpressionBasisIsRendered) {
  const int jaw = test::face_model().expression_index("jawOpen");
  ASSERT_GE(jaw, 0);
  auto first_frame = [&](const SyntheticOptions& options, std::vector<Eigen::Vector3f>& mesh) {
    auto camera = make(options);
    RgbdFrame frame;
    EXPECT_EQ(*camera->next_frame(frame, milliseconds(0)), FrameStatus::kFrame);
    mesh.assign(camera->model_vertices().begin(), camera->model_vertices().end());
    return camera->truth()->landmarks_3d;
  };
  SyntheticOptions generic;
  generic.motion = SyntheticMotion::kStatic;
  generic.frame_count = 1;
  generic.expression_weights.assign(static_cast<std::size_t>(test::face_model().expression_count),
                                    0.0f);
  generic.expression_weights[static_cast<std::size_t>(jaw)] = 1.0f;
  SyntheticOptions personal = generic;
  personal.expression_weights[static_cast<std::size_t>(jaw)] = 0.5f;
  personal.personal_expression_basis = test::face_model().expression_basis;
  for (float& v : personal.personal_expression_basis) v *= 2.0f;
  std::vector<Eigen::Vector3f> generic_mesh, personal_mesh;
  const auto generic_lm = first_frame(generic, generic_mesh);
  const auto personal_lm = first_frame(personal, personal_mesh);
  ASSERT_EQ(generic_mesh.size(), personal_mesh.size());
  double worst = 0;
  for (std::size_t v = 0; v < generic_mesh.size(); ++v)
    worst = std::max(worst, static_cast<double>((generic_mesh[v] - personal_mesh[v]).norm()));
  EXPECT_LT(worst, 1e-3);
  EXPECT_LT((generic_lm[57] - personal_lm[57]).norm(), 1e-3);  // lower lip, moved by jawOpen
  // The lower lip did move (so the comparison above is not of two neutral faces).
  SyntheticOptions neutral = generic;
  neutral.expression_weights.clear();
  std::vector<Eigen::Vector3f> neutral_mesh;
  EXPECT_GT((first_frame(neutral, neutral_mesh)[57] - generic_lm[57]).norm(), 5.0);

  SyntheticOptions wrong = personal;
  wrong.personal_expression_basis.resize(12);
  auto bad = make_synthetic_camera(test::face_model(), wrong);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message.find("personal_expression_basis"), std::string::npos);
}

TEST(SyntheticCamera, EveryDepthIsRawToMmOfItsRaw) {
  SyntheticOptions options;
  options.frame_count = 2;
  auto camera = make(options);
  RgbdFrame frame;
  ASSERT_EQ(*camera->next_frame(frame, milliseconds(0)), FrameStatus::kFrame);
  const KinectRegistration registration(camera->info().calibration);
  for (std::size_t i = 0; i < frame.depth_mm.pixels.size(); ++i) {
    const auto raw = frame.raw_disparity.pixels[i];
    ASSERT_EQ(frame.depth_mm.pixels[i], raw == kInvalidDisparity ? 0 : registration.raw_to_mm(raw));
  }
}

TEST(SyntheticCamera, SensorStatisticsOnTheFace) {
  const FaceStats near = face_stats(700.0, 4);
  const FaceStats far = face_stats(1000.0, 4);
  std::printf("face at 700 mm: mean abs error %.3f mm, holes %.1f%% of %ld px\n",
              near.mean_abs_error, 100.0 * near.hole_fraction, near.pixels);
  std::printf("face at 1000 mm: mean abs error %.3f mm, holes %.1f%% of %ld px\n",
              far.mean_abs_error, 100.0 * far.hole_fraction, far.pixels);
  EXPECT_GE(near.mean_abs_error, 1.0);
  EXPECT_LE(near.mean_abs_error, 2.0);
  // Depth noise ~ z^2: (1000 / 700)^2 = 2.04 (face depths spread a little around the nominal).
  EXPECT_NEAR(far.mean_abs_error / near.mean_abs_error, 2.04, 0.35);
  // Stated range for a frontal face: some holes (silhouette, grazing cheeks, nose shadow),
  // but most of the face is measured.
  EXPECT_GT(near.hole_fraction, 0.01);
  EXPECT_LT(near.hole_fraction, 0.15);
}

TEST(SyntheticCamera, ProjectorShadowFallsLeftOfTheHead) {
  SyntheticOptions options;
  options.motion = SyntheticMotion::kStatic;
  options.frame_count = 1;
  auto camera = make(options);
  RgbdFrame frame;
  ASSERT_EQ(*camera->next_frame(frame, milliseconds(0)), FrameStatus::kFrame);
  const auto& sensor = camera->sensor_frame();
  const auto& z = camera->truth()->noiseless_depth_mm;
  // On every row through the head, the wall shadow lies left of the head's left silhouette.
  int rows = 0, left = 0, right = 0;
  for (int y = 0; y < z.height; ++y) {
    int first = -1, last = -1;
    for (int x = 0; x < z.width; ++x) {
      if (z.at(x, y) > 0 && z.at(x, y) < options.background_mm - 100) {
        if (first < 0) first = x;
        last = x;
      }
    }
    if (first < 0) continue;
    ++rows;
    for (int x = std::max(0, first - 30); x < first; ++x)
      left += (sensor.invalid.at(x, y) & kSensorProjectorShadow) != 0;
    for (int x = last + 1; x <= std::min(z.width - 1, last + 30); ++x)
      right += (sensor.invalid.at(x, y) & kSensorProjectorShadow) != 0;
  }
  ASSERT_GT(rows, 100);
  EXPECT_GT(left, rows * 10);  // f b (1/z_head - 1/z_wall) ~ 20-30 px per row
  EXPECT_EQ(right, 0);
}

TEST(SyntheticCamera, SteadyStateFramesDoNotAllocate) {
  SyntheticOptions options;
  options.frame_count = 6;
  // An expression track exercises the per-frame mesh update too.
  std::vector<float> weights(static_cast<std::size_t>(test::face_model().expression_count), 0.0f);
  for (int i = 0; i < 6; ++i) {
    weights[test::face_model().expression_index("jawOpen")] = 0.1f * i;
    options.expression_track.push_back(weights);
  }
  auto camera = make(options);
  RgbdFrame frame;
  ASSERT_EQ(*camera->next_frame(frame, milliseconds(0)), FrameStatus::kFrame);
  ASSERT_EQ(*camera->next_frame(frame, milliseconds(0)), FrameStatus::kFrame);
  bool all_frames = true;
  long allocations = 0;
  {
    test::CountAllocations counter;
    for (int i = 0; i < 4; ++i) {
      auto status = camera->next_frame(frame, milliseconds(0));
      all_frames = all_frames && status.ok() && *status == FrameStatus::kFrame;
    }
    allocations = counter.count();
  }
  EXPECT_TRUE(all_frames);
  if (test::allocation_counting_available()) {
    EXPECT_EQ(allocations, 0);
  }
  EXPECT_FLOAT_EQ(
      camera->truth()->expression_weights[test::face_model().expression_index("jawOpen")], 0.5f);
}

TEST(SyntheticCamera, MeasureFramesPerSecond) {
  SyntheticOptions options;
  options.frame_count = 30;
  auto camera = make(options);
  RgbdFrame frame;
  // Thread CPU time: the one-core cost, independent of other load on the machine.
  auto cpu_seconds = [] {
    timespec ts{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
  };
  const auto wall_start = std::chrono::steady_clock::now();
  const double cpu_start = cpu_seconds();
  int frames = 0;
  while (*camera->next_frame(frame, milliseconds(0)) == FrameStatus::kFrame) ++frames;
  const double cpu = cpu_seconds() - cpu_start;
  const double wall =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  std::printf("synthetic: %d frames, %.1f fps on one core (CPU time), %.1f fps wall clock\n",
              frames, frames / cpu, frames / wall);
  RecordProperty("fps_cpu", std::to_string(frames / cpu));
  EXPECT_EQ(frames, 30);
}

}  // namespace
}  // namespace fb
