// 2D expression transfer (seed 002 section VI, algo/transfer/image_transfer.hpp): the grid tents
// against tent_mesh's on a quad mesh, the self-transfer and a cross-subject transfer on synthetic
// photographs with known truth (sim/subject/synthetic_photo.hpp), and `facebooth transfer-image`
// end to end with its errors.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>

#include <nlohmann/json.hpp>

#include "algo/core/polygon.hpp"
#include "algo/transfer/image_transfer.hpp"
#include "algo/transfer/vtc_transfer.hpp"
#include "sim/subject/synthetic_photo.hpp"
#include "storage/durable_file.hpp"
#include "storage/export/png_file.hpp"
#include "tests/common/run_command.hpp"
#include "tests/common/test_face_model.hpp"

namespace fb {
namespace {

namespace fs = std::filesystem;

// PSNR (dB) over the pixels inside the jaw line and the brows of `truth`'s landmarks.
double face_psnr(const ColorImage& out, const FacePhoto& truth) {
  std::vector<Eigen::Vector2d> poly;
  for (int k = 0; k <= 16; ++k) poly.push_back(truth.points[static_cast<std::size_t>(k)]);
  for (int k = 26; k >= 17; --k) poly.push_back(truth.points[static_cast<std::size_t>(k)]);
  double se = 0;
  long long n = 0;
  for (int y = 0; y < out.height; ++y)
    for (int x = 0; x < out.width; ++x) {
      if (!inside_polygon(poly, x, y)) continue;
      const Rgb8 a = out.at(x, y), b = truth.image.at(x, y);
      se += std::pow(a.r - b.r, 2.0) + std::pow(a.g - b.g, 2.0) + std::pow(a.b - b.b, 2.0);
      n += 3;
    }
  return 10.0 * std::log10(255.0 * 255.0 / std::max(se / static_cast<double>(n), 1e-12));
}

// Mean luminance error against the truth inside the truth's inner mouth (landmarks 60-67).
double mouth_error(const ColorImage& out, const FacePhoto& truth) {
  double lo_x = 1e9, hi_x = -1e9, lo_y = 1e9, hi_y = -1e9;
  for (int k = 60; k < 68; ++k) {
    const auto& p = truth.points[static_cast<std::size_t>(k)];
    lo_x = std::min(lo_x, p.x()), hi_x = std::max(hi_x, p.x());
    lo_y = std::min(lo_y, p.y()), hi_y = std::max(hi_y, p.y());
  }
  auto lum = [](Rgb8 c) { return 0.299 * c.r + 0.587 * c.g + 0.114 * c.b; };
  double sum = 0;
  int n = 0;
  for (int y = static_cast<int>(lo_y); y <= static_cast<int>(hi_y); ++y)
    for (int x = static_cast<int>(lo_x); x <= static_cast<int>(hi_x); ++x) {
      sum += std::abs(lum(out.at(x, y)) - lum(truth.image.at(x, y)));
      ++n;
    }
  return n > 0 ? sum / n : 1e9;
}

FacePhoto photo(std::uint64_t subject, const std::string& expression) {
  PhotoSpec spec;
  spec.subject = subject;
  if (!expression.empty()) {
    for (const auto& [name, w] : photo_expressions(test::face_model()))
      if (name == expression) spec.expression_weights = w;
    EXPECT_FALSE(spec.expression_weights.empty()) << expression;
  }
  auto p = render_photo(test::face_model(), spec);
  EXPECT_TRUE(p) << p.error().message;
  return std::move(*p);
}

TEST(ImageTransfer, GridTentsAreTentMeshTents) {
  // Two random height grids: the per-pixel Q of the grid tents equals VtcSource's on the same
  // grid as a quad mesh.
  const int w = 9, h = 7;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0.0, 40.0);
  std::vector<double> a(w * h), b(w * h);
  for (auto& v : a) v = u(rng);
  for (auto& v : b) v = u(rng);
  std::vector<std::uint32_t> quads;
  for (int y = 0; y + 1 < h; ++y)
    for (int x = 0; x + 1 < w; ++x)
      for (int q : {y * w + x, y * w + x + 1, (y + 1) * w + x + 1, (y + 1) * w + x})
        quads.push_back(static_cast<std::uint32_t>(q));
  auto faces = faces_of(w * h, quads, 4);
  ASSERT_TRUE(faces);
  Points pa(w * h, 3), pb(w * h, 3);
  for (int i = 0; i < w * h; ++i) {
    pa.row(i) << i % w, i / w, a[static_cast<std::size_t>(i)];
    pb.row(i) << i % w, i / w, b[static_cast<std::size_t>(i)];
  }
  auto source = VtcSource::create(tent_topology(*faces), pa);
  ASSERT_TRUE(source);
  auto q = source->transformations(pb);
  ASSERT_TRUE(q);
  double worst = 0;
  for (int y = 1; y + 1 < h; ++y)
    for (int x = 1; x + 1 < w; ++x) {
      const Eigen::Matrix3d grid = grid_tent(b, w, x, y).w * grid_tent(a, w, x, y).inverse;
      worst =
          std::max(worst, (grid - (*q)[static_cast<std::size_t>(y * w + x)]).cwiseAbs().maxCoeff());
    }
  EXPECT_LT(worst, 1e-9);
}

TEST(ImageTransfer, SelfTransferReproducesTheExpressionPhotograph) {
  const FacePhoto neutral = photo(3, "");
  for (const std::string e : {"smile", "jaw_open_brows_up"}) {
    const FacePhoto expr = photo(3, e);
    auto out = transfer_image_expression(neutral, expr, neutral);
    ASSERT_TRUE(out) << out.error().message;
    EXPECT_EQ(out->image.width, 311);
    EXPECT_EQ(out->image.height, 419);
    const double vtc = face_psnr(out->image, expr), before = face_psnr(neutral.image, expr);
    EXPECT_GE(vtc, 30.0) << e;
    EXPECT_GT(vtc, before + 5.0) << e;  // the expression is there, not the neutral
  }
}

TEST(ImageTransfer, CrossSubjectCarriesTheMouthShadingTheWarpMisses) {
  // Subject 1's open mouth onto subject 2: the warp alone stretches the lips over the opening;
  // the VTC solve brings the source's dark mouth cavity.
  const FacePhoto source = photo(1, ""), source_expr = photo(1, "jaw_open_brows_up");
  const FacePhoto target = photo(2, ""), truth = photo(2, "jaw_open_brows_up");
  auto out = transfer_image_expression(source, source_expr, target);
  ASSERT_TRUE(out) << out.error().message;
  const double vtc = mouth_error(out->image, truth), warp = mouth_error(out->warped, truth);
  EXPECT_LT(vtc, 0.8 * warp) << "inner-mouth luminance error, levels";
  EXPECT_GE(face_psnr(out->image, truth), 24.0);
  EXPECT_GT(out->region_pixels, 10000);
  EXPECT_LT(out->relative_residual, 3e-3 + 1e-12);
}

TEST(ImageTransfer, RefusesSourcePhotographsOfDifferentSizes) {
  FacePhoto a = photo(1, ""), b = a, t = a;
  b.image.resize(200, 200);
  auto out = transfer_image_expression(a, b, t);
  ASSERT_FALSE(out);
  EXPECT_NE(out.error().message.find("differ in size"), std::string::npos);
}

class TransferImageCli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("facebooth-transfer-image-" + std::to_string(::getpid()) + "-" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  void write(const FacePhoto& p, const std::string& stem) {
    auto png = encode_png(p.image);
    ASSERT_TRUE(png);
    ASSERT_TRUE(write_file_durably(dir_ / (stem + ".png"), *png));
    std::ofstream l(dir_ / (stem + ".txt"));
    for (const auto& q : p.points) l << q.x() << " " << q.y() << "\n";
  }
  test::CommandRun facebooth(const std::string& args) {
    return test::run_command(std::string(FB_CLI_PATH) + " transfer-image " + args,
                             test::Stderr::kMerged);
  }
  fs::path dir_;
};

TEST_F(TransferImageCli, WritesTheTransferAndSaysWhatIsWrong) {
  const FacePhoto neutral = photo(1, ""), expr = photo(1, "smile"), target = photo(2, "");
  write(neutral, "a");
  write(expr, "b");
  write(target, "c");
  const std::string inputs = "--source-neutral " + path("a.png") + " --source-expr " +
                             path("b.png") + " --target " + path("c.png");
  const std::string marks =
      " --landmarks " + path("a.txt") + "," + path("b.txt") + "," + path("c.txt");
  auto ok = facebooth(inputs + marks + " --out " + path("d.png"));
  ASSERT_EQ(ok.exit_code, 0) << ok.out;
  auto bytes = read_file_bytes(dir_ / "d.png");
  ASSERT_TRUE(bytes);
  auto d = decode_png(*bytes);
  ASSERT_TRUE(d);
  EXPECT_EQ(d->width, 311);
  EXPECT_EQ(d->height, 419);
  const auto json = nlohmann::json::parse(ok.out.substr(ok.out.find('{')));
  EXPECT_GT(json["face_pixels"].get<int>(), 10000);

  auto exists = facebooth(inputs + marks + " --out " + path("d.png"));
  EXPECT_NE(exists.exit_code, 0);
  EXPECT_NE(exists.out.find("already exists"), std::string::npos) << exists.out;

  auto missing =
      facebooth("--source-neutral " + path("nope.png") + " --source-expr " + path("b.png") +
                " --target " + path("c.png") + " --out " + path("e.png"));
  EXPECT_NE(missing.exit_code, 0);
  EXPECT_NE(missing.out.find("nope.png: no such file"), std::string::npos) << missing.out;

  FacePhoto small = expr;
  small.image.resize(100, 120);
  write(small, "small");
  auto size =
      facebooth("--source-neutral " + path("a.png") + " --source-expr " + path("small.png") +
                " --target " + path("c.png") + marks + " --out " + path("f.png"));
  EXPECT_NE(size.exit_code, 0);
  EXPECT_NE(size.out.find("differ in size"), std::string::npos) << size.out;

  auto short_marks =
      facebooth(inputs + " --landmarks " + path("a.txt") + " --out " + path("g.png"));
  EXPECT_NE(short_marks.exit_code, 0);
  EXPECT_NE(short_marks.out.find("three files"), std::string::npos) << short_marks.out;
}

TEST_F(TransferImageCli, SaysWhenDlibFindsNoFace) {
  if (!fs::exists("/usr/share/dlib/shape_predictor_68_face_landmarks.dat"))
    GTEST_SKIP() << "Debian libdlib-data is not installed";
  FacePhoto blank;
  blank.image.resize(311, 419);
  for (auto& p : blank.image.pixels) p = {128, 128, 128};
  write(blank, "blank");
  write(photo(1, ""), "a");
  auto run = facebooth("--source-neutral " + path("a.png") + " --source-expr " + path("a.png") +
                       " --target " + path("blank.png") + " --out " + path("d.png"));
  EXPECT_NE(run.exit_code, 0);
  EXPECT_NE(run.out.find("no face found in --target"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("--landmarks"), std::string::npos) << run.out;
  EXPECT_FALSE(fs::exists(dir_ / "d.png"));
}

}  // namespace
}  // namespace fb
