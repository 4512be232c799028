// The realistic synthetic world (sim/camera/synthetic_world.hpp): each option
// changes what it should, scored against the camera's own ground truth, and the defaults leave
// frames as they were.
#include "sim/camera/synthetic_world.hpp"

#include <Eigen/Dense>
#include <cmath>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "algo/landmarks/landmark_detector.hpp"
#include "sim/camera/synthetic_camera.hpp"
#include "sim/camera/world_presets.hpp"
#include "tests/common/test_face_model.hpp"

namespace fb {
namespace {

using std::chrono::milliseconds;

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

bool next(SyntheticCamera& camera, RgbdFrame& frame) {
  auto status = camera.next_frame(frame, milliseconds(0));
  return status.ok() && *status == FrameStatus::kFrame;
}

// Pixels inside the bounding box of the 68 true landmarks with a rendered head.
template <class F>
void for_face_box(const FrameTruth& truth, F&& f) {
  double x0 = 1e9, x1 = -1e9, y0 = 1e9, y1 = -1e9;
  for (const auto& p : truth.landmarks_depth_px) {
    x0 = std::min(x0, p.x()), x1 = std::max(x1, p.x());
    y0 = std::min(y0, p.y()), y1 = std::max(y1, p.y());
  }
  for (int y = static_cast<int>(y0); y <= static_cast<int>(y1); ++y)
    for (int x = static_cast<int>(x0); x <= static_cast<int>(x1); ++x)
      if (truth.noiseless_depth_mm.contains(x, y) && truth.noiseless_depth_mm.at(x, y) > 0.0f)
        f(x, y);
}

TEST(SyntheticWorld, NoWorldKeysAndWorldNoneGiveIdenticalFrames) {
  auto a = open_uri("seed=4,frames=1");
  auto b = open_uri("seed=4,frames=1,world=none");
  RgbdFrame fa, fb;
  ASSERT_TRUE(next(*a, fa));
  ASSERT_TRUE(next(*b, fb));
  EXPECT_EQ(fa.raw_disparity.pixels, fb.raw_disparity.pixels);
  EXPECT_TRUE(std::equal(fa.color.pixels.begin(), fa.color.pixels.end(), fb.color.pixels.begin(),
                         [](Rgb8 p, Rgb8 q) { return p.r == q.r && p.g == q.g && p.b == q.b; }));
  EXPECT_EQ(a->truth()->face_hidden_fraction, 0.0);
}

TEST(SyntheticWorld, BadWorldValuesSayWhatIsAccepted) {
  auto bad = parse_synthetic_options("world=fancy", test::face_model());
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message.find("realistic|identity|texture|hair|clutter|noise|unit"),
            std::string::npos)
      << bad.error().message;
  auto tone = parse_synthetic_options("tone=3", test::face_model());
  ASSERT_FALSE(tone.ok());
  EXPECT_NE(tone.error().message.find("tone"), std::string::npos);
}

// The true (rendered) rest mesh of an out-of-span identity is >= 2 mm from its least-squares
// projection onto the model's identity span somewhere on the face; an in-span one is not.
double distance_to_span(const std::string& uri) {
  const FaceModel& m = test::face_model();
  auto camera = open_uri(uri);
  const auto vertices = camera->model_vertices();
  const int V = m.face_vertex_count, K = m.identity_count;
  Eigen::MatrixXd basis(3 * V, K);
  Eigen::VectorXd target(3 * V);
  for (int k = 0; k < K; ++k) {
    const auto mode = m.identity_mode(k);
    for (int i = 0; i < 3 * V; ++i) basis(i, k) = mode[i];
  }
  for (int v = 0; v < V; ++v)
    for (int a = 0; a < 3; ++a) target(3 * v + a) = vertices[v][a] - m.neutral[3 * v + a];
  const Eigen::VectorXd c = (basis.transpose() * basis).ldlt().solve(basis.transpose() * target);
  const Eigen::VectorXd r = target - basis * c;
  double worst = 0.0;
  for (int v = 0; v < V; ++v) worst = std::max(worst, r.segment<3>(3 * v).norm());
  return worst;
}

TEST(SyntheticWorld, OutOfSpanIdentityIsFarFromTheModelSpanAndTruthFollowsIt) {
  EXPECT_LT(distance_to_span("seed=2,frames=1,motion=static"), 0.2);
  EXPECT_GE(distance_to_span("seed=2,frames=1,motion=static,world=identity"), 2.0);
  auto camera = open_uri("seed=2,frames=1,motion=static,world=identity");
  RgbdFrame frame;
  ASSERT_TRUE(next(*camera, frame));
  const FrameTruth& truth = *camera->truth();
  for (int k = 0; k < 3; ++k) EXPECT_GE(std::abs(truth.identity_coeffs[k]), 3.5f);
  // The truth landmarks are the displaced mesh's vertices.
  const auto vertices = camera->model_vertices();
  for (int l = 0; l < 68; ++l) {
    const Eigen::Vector3d p = truth.camera_from_model.apply(
        vertices[test::face_model().landmark_vertices[l]].cast<double>());
    EXPECT_LT((p - truth.landmarks_3d[l]).norm(), 1e-6);
  }
}

struct MissingFractions {
  double cap = 0, face = 0, cap_error_mm = 0;
};

MissingFractions hair_missing(const std::string& uri, const SyntheticCamera* reference) {
  auto camera = open_uri(uri);
  RgbdFrame frame;
  EXPECT_TRUE(next(*camera, frame));
  const auto material = (reference ? reference : camera.get())->material_pixels();
  const FrameTruth& truth = *camera->truth();
  long cap = 0, cap_missing = 0, face = 0, face_missing = 0;
  double cap_error = 0;
  const int w = frame.depth_mm.width;
  for (int y = 0; y < frame.depth_mm.height; ++y)
    for (int x = 0; x < w; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * w + x;
      if (truth.noiseless_depth_mm.pixels[i] <= 0.0f || material.empty()) continue;
      if (material[i].hair < 0.5f) continue;
      ++cap;
      if (frame.depth_mm.pixels[i] == 0)
        ++cap_missing;
      else
        cap_error += std::abs(frame.depth_mm.pixels[i] - truth.noiseless_depth_mm.pixels[i]);
    }
  for_face_box(truth, [&](int x, int y) {
    const std::size_t i = static_cast<std::size_t>(y) * w + x;
    if (!material.empty() && (material[i].hair > 0.05f || material[i].beard > 0.05f)) return;
    ++face;
    face_missing += frame.depth_mm.at(x, y) == 0;
  });
  return {static_cast<double>(cap_missing) / std::max(cap, 1L),
          static_cast<double>(face_missing) / std::max(face, 1L),
          cap_error / std::max(cap - cap_missing, 1L)};
}

TEST(SyntheticWorld, HairCapLosesDepthTheFaceDoesNot) {
  const std::string base = "seed=3,frames=1,motion=static,distance=750";
  auto hair = open_uri(base + ",hair=on");
  RgbdFrame frame;
  ASSERT_TRUE(next(*hair, frame));
  const MissingFractions with = hair_missing(base + ",hair=on", nullptr);
  const MissingFractions without = hair_missing(base, hair.get());
  // Measured (seed 3): 61 % of the cap's pixels without depth with hair, 25 % without (the top
  // of the head is seen at a grazing angle); hair is measured 7.9 mm off the scalp vs 1.9 mm.
  EXPECT_GE(with.cap, without.cap + 0.25) << "hair cap dropouts";
  EXPECT_GT(with.cap_error_mm, without.cap_error_mm + 4.0) << "hair is measured off the scalp";
  EXPECT_NEAR(with.face, without.face, 0.01) << "the face outside hair and beard is unchanged";
}

TEST(SyntheticWorld, HandPassHidesTheFaceAndTheTruthSaysSo) {
  auto camera = open_uri("seed=1,frames=40,motion=static,hand_pass=5");
  RgbdFrame frame;
  std::vector<double> hidden;
  std::vector<double> hand_depth_below_face;
  while (next(*camera, frame)) {
    const FrameTruth& t = *camera->truth();
    hidden.push_back(t.face_hidden_fraction);
  }
  ASSERT_EQ(hidden.size(), 40u);
  EXPECT_EQ(hidden[0], 0.0);
  EXPECT_EQ(hidden[4], 0.0);
  EXPECT_EQ(hidden[39], 0.0);
  // Middle of the 30-frame pass (frames 5-34).
  for (int f = 16; f <= 23; ++f) EXPECT_GE(hidden[f], 0.3) << "frame " << f;
  // The depth there is the hand's, well in front of the face.
  auto again = open_uri("seed=1,frames=21,motion=static,hand_pass=5");
  for (int f = 0; f < 21; ++f) ASSERT_TRUE(next(*again, frame));
  const FrameTruth& t = *again->truth();
  const Eigen::Vector2d nose = t.landmarks_depth_px[30];
  const double face_z = t.landmarks_3d[30].z();
  double nearest = 1e9;
  for (int dy = -6; dy <= 6; ++dy)
    for (int dx = -6; dx <= 6; ++dx) {
      const auto mm =
          frame.depth_mm.at(static_cast<int>(nose.x()) + dx, static_cast<int>(nose.y()) + dy);
      if (mm > 0) nearest = std::min(nearest, static_cast<double>(mm));
    }
  EXPECT_LT(nearest, face_z - 60.0);
}

TEST(SyntheticWorld, ClutterIsNearerThanTheFaceAndTheFaceIsOffCentre) {
  auto camera = open_uri("seed=1,frames=1,motion=static,torso=on,desk=on,hand=on,offset_y=-80");
  RgbdFrame frame;
  ASSERT_TRUE(next(*camera, frame));
  const FrameTruth& t = *camera->truth();
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  double face_z = 0;
  for (int l = 0; l < 68; ++l) centre += t.landmarks_depth_px[l] / 68.0;
  for (int l = 0; l < 68; ++l) face_z += t.landmarks_3d[l].z() / 68.0;
  const auto& k = camera->info().depth_intrinsics;
  EXPECT_NEAR(centre.y(), k.cy - 80.0, 3.0);
  EXPECT_NEAR(centre.x(), k.cx, 3.0);
  // The bottom rows hold measured surfaces nearer than the face (chest, desk, arm).
  long nearer = 0;
  for (int y = frame.depth_mm.height - 40; y < frame.depth_mm.height; ++y)
    for (int x = 0; x < frame.depth_mm.width; ++x) {
      const auto mm = frame.depth_mm.at(x, y);
      nearer += mm > 0 && mm < face_z - 30.0;
    }
  EXPECT_GT(nearer, 2000);
  EXPECT_EQ(t.face_hidden_fraction, 0.0) << "the resting hand is beside the face";
}

// Correlation of the depth error between pixels 2 apart on the wall.
double neighbour_error_correlation(const std::string& uri, double* speckle = nullptr) {
  auto camera = open_uri(uri);
  RgbdFrame frame;
  EXPECT_TRUE(next(*camera, frame));
  const FrameTruth& t = *camera->truth();
  double sxy = 0, sxx = 0, syy = 0, sx = 0, sy = 0;
  long n = 0, wall = 0, speckled = 0;
  for (int y = 10; y < 100; ++y)
    for (int x = 10; x < 200; ++x) {
      const auto& inv = camera->sensor_frame().invalid;
      ++wall;
      speckled += (inv.at(x, y) & kSensorSpeckle) != 0;
      const auto a = frame.depth_mm.at(x, y), b = frame.depth_mm.at(x + 2, y);
      if (a == 0 || b == 0) continue;
      const double ea = a - t.noiseless_depth_mm.at(x, y),
                   eb = b - t.noiseless_depth_mm.at(x + 2, y);
      sxy += ea * eb, sxx += ea * ea, syy += eb * eb, sx += ea, sy += eb;
      ++n;
    }
  if (speckle) *speckle = static_cast<double>(speckled) / wall;
  const double cov = sxy / n - (sx / n) * (sy / n);
  return cov / std::sqrt((sxx / n - (sx / n) * (sx / n)) * (syy / n - (sy / n) * (sy / n)));
}

TEST(SyntheticWorld, BlockNoiseIsCorrelatedAndSpeckleHolesAppear) {
  const std::string base = "seed=5,frames=1,motion=static,background=900";
  EXPECT_LT(neighbour_error_correlation(base), 0.15);
  double speckle = 0;
  // 0.81 of the 2.5 raw^2 error variance is block-correlated (0.9 raw of 1.3 per pixel): 0.26.
  EXPECT_GT(neighbour_error_correlation(base + ",world=noise", &speckle), 0.2);
  EXPECT_GT(speckle, 0.002);
  EXPECT_LT(speckle, 0.01);
}

double mean_face_luma(const std::string& uri) {
  auto camera = open_uri(uri);
  RgbdFrame frame;
  EXPECT_TRUE(next(*camera, frame));
  const auto& px = camera->truth()->landmarks_color_px;
  double sum = 0;
  int n = 0;
  for (int l : {1, 15, 29, 31, 35}) {
    const Rgb8 c = frame.color.at(static_cast<int>(px[l].x()), static_cast<int>(px[l].y()));
    sum += 0.3 * c.r + 0.59 * c.g + 0.11 * c.b;
    ++n;
  }
  return sum / n;
}

TEST(SyntheticWorld, SkinToneRangesFromPaleToDark) {
  const double pale = mean_face_luma("seed=1,frames=1,motion=static,texture=on,tone=0");
  const double dark = mean_face_luma("seed=1,frames=1,motion=static,texture=on,tone=1");
  EXPECT_GT(pale, 2.0 * dark);
}

// dlib runs on the textured renders as on a photo: it finds the face and places the points
// (mean over the 68, colour image) within a threshold measured on seeds 1-4 (see
// docs/realistic-world.md): 2.3-3.4 px, asserted at 5 px.
TEST(SyntheticWorld, DlibFindsTexturedFaces) {
  constexpr const char* kPredictor = "/usr/share/dlib/shape_predictor_68_face_landmarks.dat";
  if (!std::filesystem::exists(kPredictor)) GTEST_SKIP() << "libdlib-data not installed";
  std::ifstream in(kPredictor, std::ios::binary);
  auto detector = LandmarkDetector::create(in);
  ASSERT_TRUE(detector.ok());
  for (int seed = 1; seed <= 4; ++seed) {
    auto camera = open_uri("seed=" + std::to_string(seed) +
                           ",frames=1,motion=static,world=texture,hair=on,beard=on");
    RgbdFrame frame;
    ASSERT_TRUE(next(*camera, frame));
    detector->reset_tracking();
    auto found = detector->detect(frame.color);
    ASSERT_TRUE(found.ok()) << "seed " << seed << ": " << found.error().message;
    double error = 0;
    for (int l = 0; l < 68; ++l)
      error += (found->points[l] - camera->truth()->landmarks_color_px[l]).norm() / 68.0;
    EXPECT_LT(error, 5.0) << "seed " << seed;
  }
}

}  // namespace
}  // namespace fb
