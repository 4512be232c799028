// The exemplar image operations against known inputs, and the shipped exemplar set against the
// converter run on the real scan (byte for byte).
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "algo/wrinkles/exemplar.hpp"
#include "algo/wrinkles/salient_regions.hpp"

namespace fb {
namespace {

namespace fs = std::filesystem;

FloatImage make(int w, int h, auto f) {
  FloatImage im;
  im.resize(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) im.at(x, y) = static_cast<float>(f(x, y));
  return im;
}

TEST(Exemplar, HighPassKeepsWrinklesAndDropsTheFaceShape) {
  // A steep ramp (the face's shape) plus fine ripples of 6 px period (wrinkles).
  const auto in =
      make(200, 60, [](int x, int) { return 0.5 * x + 2.0 * std::sin(x * 2 * M_PI / 6); });
  const FloatImage hp = high_pass(in, 10.0);
  double err = 0.0;
  int n = 0;
  for (int x = 40; x < 160; ++x, ++n)
    err += std::abs(hp.at(x, 30) - 2.0 * std::sin(x * 2 * M_PI / 6));
  EXPECT_LT(err / n, 0.1);  // the ripple survives, the ramp is gone
}

TEST(Exemplar, ShadingLightsTheWallThatFacesTheKeyLight) {
  // A horizontal groove 0.3 mm deep: under a light from above, its lower wall faces up (lit),
  // its upper wall faces down (darker); flat skin reads albedo x (ambient + diffuse l_z).
  const auto groove =
      make(40, 40, [](int, int y) { return -0.3 * std::exp(-0.5 * (y - 20) * (y - 20) / 4.0); });
  const FloatImage s = shade_relief(groove, 0.25);
  const SkinLight light;
  EXPECT_NEAR(s.at(20, 2), light.albedo * (light.ambient + light.diffuse * light.to_light.z()),
              1e-3);
  EXPECT_GT(s.at(20, 22), s.at(20, 2) + 0.02);  // below the centre: faces up, towards the light
  EXPECT_LT(s.at(20, 18), s.at(20, 2) - 0.02);  // above: faces down, away from it
}

TEST(Exemplar, RotationTurnsStripesAndGradientsFollow) {
  const auto stripes = make(101, 101, [](int, int y) { return std::sin(y * 2 * M_PI / 10); });
  const FloatImage turned = rotate_square(stripes, 90.0, 70);
  auto energy = [](const FloatImage& im) {
    const ImageGradient g = image_gradient(im);
    double ex = 0, ey = 0;
    for (std::size_t i = 0; i < g.gx.pixels.size(); ++i) {
      ex += g.gx.pixels[i] * g.gx.pixels[i];
      ey += g.gy.pixels[i] * g.gy.pixels[i];
    }
    return std::make_pair(ex, ey);
  };
  const auto [sx, sy] = energy(stripes);
  const auto [tx, ty] = energy(turned);
  EXPECT_LT(sx, 1e-6 * sy);  // horizontal stripes vary along y only
  EXPECT_LT(ty, 0.01 * tx);  // turned a quarter: along x only
  const FloatImage same = resample(stripes, 0.5);
  EXPECT_EQ(same.width, 51);
}

// A face-like patch: two forehead grooves, a groove at the mouth, and pores. The forehead lines
// form one region (grown by the margin); the mouth's line is dropped for its landmarks, the
// pores for their length.
TEST(SalientRegions, ForeheadLinesFoundMouthAndPoresLeftOut) {
  auto groove = [](double d, double sigma) {
    return -0.3 * std::exp(-0.5 * d * d / (sigma * sigma));
  };
  const auto height = make(200, 160, [&](int x, int y) {
    double z = 0.0;
    if (x >= 40 && x < 160) z += groove(y - 40, 1.5) + groove(y - 50, 1.5);
    if (x >= 80 && x < 120) z += groove(y - 130, 1.5);
    if ((x * 7 + y * 13) % 97 == 0) z += 0.05;  // pores: single-pixel bumps
    return z;
  });
  const FloatImage lum = shade_relief(height, 0.25);
  std::array<Eigen::Vector2d, 68> landmarks;
  for (int i = 0; i < 68; ++i) landmarks[static_cast<std::size_t>(i)] = {100.0, 300.0};  // far away
  for (int i = 48; i < 68; ++i)  // the lips along the mouth line
    landmarks[static_cast<std::size_t>(i)] = {80.0 + 2.0 * (i - 48), 130.0};
  SalientOptions o;
  o.inside_face_only = false;  // the landmarks here mark the mouth only, no face outline
  o.wrinkle_zones = false;     // the paper's detector (the zones need a face's landmarks)
  const SalientRegions r = salient_regions(lum, landmarks, o);
  ASSERT_EQ(r.regions.size(), 1u);
  const PixelRect& f = r.regions.front();
  EXPECT_TRUE(f.contains(45, 40) && f.contains(155, 50));  // both lines, end to end
  EXPECT_LE(f.y0, 40 - 5);                                 // grown by the 5 px margin
  EXPECT_LT(f.y1, 70);                                     // not down to the mouth
  for (const auto& l : r.lines) EXPECT_GE(l.length(), 12);
  // Without landmarks the mouth's line is a region of its own.
  EXPECT_EQ(salient_regions(lum, std::nullopt, o).regions.size(), 2u);
}

// Round 6: a crow's-feet ray joined to a long groove outside the zone (as the shadowed side's
// noise joined the rays to the face's silhouette) is one component centred off the zone and was
// dropped; traced without crossing the crow's-feet zone's border, the ray is a region there.
TEST(SalientRegions, CrowsFeetRayCutFromWhatJoinsItOutsideItsZone) {
  auto groove = [](double d) { return -0.3 * std::exp(-0.5 * d * d / (1.5 * 1.5)); };
  const auto height = make(200, 160, [&](int x, int y) {
    double z = 0.0;
    if (x >= 155 && x < 186) z += groove(y - 100);             // the ray, on to the "silhouette"
    if (y >= 20 && y < 150 && y != 100) z += groove(x - 186);  // the long groove outside
    return z;
  });
  const FloatImage lum = shade_relief(height, 0.25);
  std::array<Eigen::Vector2d, 68> l;
  for (auto& p : l) p = {100.0, 400.0};  // off the image: no feature near the ray
  l[0] = {20, 150}, l[16] = {180, 150};  // jaw 160 px wide
  for (int i = 0; i < 5; ++i) l[17 + i] = {40.0 + 12.5 * i, 60}, l[22 + i] = {110.0 + 12.5 * i, 60};
  l[27] = {100, 80};
  for (int i = 0; i < 6; ++i) {  // eyes: 36 and 45 are the outer corners
    l[36 + i] = {50.0 + 6.0 * (i % 4), 100.0 + (i < 4 ? -2.0 : 2.0)};
    l[42 + i] = {126.0 + 6.0 * (i % 4), 100.0 + (i < 4 ? -2.0 : 2.0)};
  }
  l[36] = {50, 100}, l[45] = {150, 100};
  SalientOptions o;
  const auto zones = wrinkle_zones(l, o);
  ASSERT_TRUE(zones[3].contains(160, 100));
  auto found = [&](int trace) {
    o.trace_in_zones = trace;
    const SalientRegions r = salient_regions(lum, l, o);
    for (const auto& reg : r.regions)
      if (reg.contains(160, 100) && reg.contains(170, 100)) return true;
    return false;
  };
  EXPECT_FALSE(found(0));  // round 5: one component, centred outside the zone
  EXPECT_TRUE(found(1));
}

TEST(Exemplar, TheShippedSetIsWhatTheConverterMakesFromTheScan) {
  const fs::path shipped = fs::path(FB_DATA_DIR) / "wrinkle_exemplars";
  auto doc = nlohmann::json::parse(std::ifstream(shipped / "exemplars.json"));
  ASSERT_EQ(doc["exemplars"].size(), 24u);  // 4 regions x angles 0, 30, ..., 150
  for (const auto& e : doc["exemplars"]) {
    EXPECT_TRUE(fs::exists(shipped / e["height_png"].get<std::string>()));
    EXPECT_TRUE(fs::exists(shipped / e["shading_png"].get<std::string>()));
    const double p99 = e["height_p99_mm"];
    EXPECT_GT(p99, 0.1) << e["name"];  // wrinkle relief, 0.1-1 mm (SOURCE.md)
    EXPECT_LT(p99, 1.0) << e["name"];
  }
  EXPECT_TRUE(fs::exists(shipped / "ATTRIBUTION.md"));
  const fs::path source = fs::path(FB_SHARED_DIR) / "skin" / "lps";
  if (!fs::exists(source / "Infinite-Level_02_Disp_NoSmoothUV-4096.jpg"))
    GTEST_SKIP() << "../shared/skin/lps is absent: the shipped set is checked, not remade";
  const fs::path out = fs::temp_directory_path() / ("fb-exemplars-" + std::to_string(::getpid()));
  const std::string cmd = std::string(FB_CONVERT_EXEMPLARS) + " --source " + source.string() +
                          " --out " + out.string() + " > /dev/null";
  ASSERT_EQ(std::system(cmd.c_str()), 0);
  for (const auto& entry : fs::directory_iterator(shipped)) {
    std::ifstream a(entry.path(), std::ios::binary),
        b(out / entry.path().filename(), std::ios::binary);
    const std::string x((std::istreambuf_iterator<char>(a)), {}),
        y((std::istreambuf_iterator<char>(b)), {});
    EXPECT_EQ(x, y) << entry.path().filename();
  }
  fs::remove_all(out);
}

}  // namespace
}  // namespace fb
