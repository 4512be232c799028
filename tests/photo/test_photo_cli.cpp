// `facebooth photo animate` and `facebooth photo edit` as a user runs them: a synthetic
// textured photo, a small bilinear model file and a take in a real session store; the frames,
// the strip and (with img2webp or ffmpeg installed) the video are written; the errors for an
// unknown attribute, a bad number and a photo without a face say what to do.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>

#include <nlohmann/json.hpp>

#include "host/cli/photo_pipeline.hpp"
#include "storage/take_writer.hpp"
#include "tests/common/run_command.hpp"
#include "tests/photo/photo_fixture.hpp"

namespace fb {
namespace {

namespace fs = std::filesystem;

struct TempDir {
  fs::path path;
  TempDir() {
    path = fs::temp_directory_path() / ("fb-photo-" + std::to_string(std::random_device{}()));
    fs::create_directories(path);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

std::string cli() {
  return std::string(FB_CLI_PATH);
}

// photo.png, model.fbbm and store/ with one 12-frame take opening the jaw.
struct Inputs {
  TempDir dir;
  TakeId take = 0;
  Inputs() {
    const auto r = test::render_faces(11, {test::model_weights({})});
    EXPECT_TRUE(cli::write_photo(r.frames[0], dir.path / "photo.png").ok());
    const auto bytes = serialize_bilinear_model(test::photo_model());
    std::ofstream(dir.path / "model.fbbm", std::ios::binary)
        .write(reinterpret_cast<const char*>(bytes.data()),
               static_cast<std::streamsize>(bytes.size()));
    auto store = SessionStore::open(dir.path / "store");
    EXPECT_TRUE(store.ok());
    auto subject = store->add_subject("performer");
    EXPECT_TRUE(subject.ok());
    TakeWriter w(std::vector<std::string>(kArkitNames.begin(), kArkitNames.end()), 30);
    for (int f = 0; f < 12; ++f)
      EXPECT_TRUE(w.add_frame(f / 30.0, RigidPose{},
                              test::arkit_curves(
                                  {{"jawOpen", 0.06f * f}, {"eyeBlinkLeft", f > 6 ? 1.0f : 0.0f}}))
                      .ok());
    auto id = w.store(*store, *subject, std::nullopt);
    EXPECT_TRUE(id.ok());
    take = *id;
  }
};

TEST(PhotoCli, AnimateWritesTheFramesTheStripAndAVideoWhenAnEncoderIsInstalled) {
  Inputs in;
  const fs::path out = in.dir.path / "anim";
  const auto run = test::run_command(
      cli() + " photo animate --in " + (in.dir.path / "photo.png").string() + " --model " +
          (in.dir.path / "model.fbbm").string() + " --store " + (in.dir.path / "store").string() +
          " --take " + std::to_string(in.take) + " --out " + out.string() + " --strip " +
          (in.dir.path / "strip.png").string(),
      test::Stderr::kDropped);
  ASSERT_EQ(run.exit_code, 0) << run.out;
  const auto j = nlohmann::json::parse(run.out);
  EXPECT_EQ(j["frames"], 12);
  EXPECT_LT(j["landmark_fit_error_px"].get<double>(), 3.0);
  EXPECT_GT(j["max_shift_px"].get<double>(), 5.0);  // the jaw opened
  for (int f = 0; f < 12; ++f) {
    char name[32];
    std::snprintf(name, sizeof name, "frame_%04d.png", f);
    EXPECT_TRUE(fs::exists(out / name)) << name;
  }
  auto frame = cli::read_photo(out / "frame_0011.png");
  auto photo = cli::read_photo(in.dir.path / "photo.png");
  ASSERT_TRUE(frame.ok() && photo.ok());
  EXPECT_EQ(frame->width, photo->width);
  auto strip = cli::read_photo(in.dir.path / "strip.png");
  ASSERT_TRUE(strip.ok());
  EXPECT_GT(strip->width, 3 * strip->height);  // the photo and 3 frames side by side
  const bool encoder = fs::exists("/usr/bin/ffmpeg") || fs::exists("/usr/bin/img2webp");
  if (encoder) {
    ASSERT_TRUE(j["video"].is_string()) << run.out;
    EXPECT_GT(fs::file_size(j["video"].get<std::string>()), 1000u);
  } else {
    EXPECT_TRUE(j["video"].is_null());
    EXPECT_NE(j["video_note"].get<std::string>().find("apt-get install"), std::string::npos);
  }
}

TEST(PhotoCli, AVideoFolderDrivesThePhoto) {
  // The performer's frames: the photo's own frames opening the jaw, from animate itself.
  Inputs in;
  const fs::path video = in.dir.path / "video";
  const auto first = test::run_command(
      cli() + " photo animate --in " + (in.dir.path / "photo.png").string() + " --model " +
          (in.dir.path / "model.fbbm").string() + " --store " + (in.dir.path / "store").string() +
          " --take " + std::to_string(in.take) + " --every 3 --out " + video.string(),
      test::Stderr::kDropped);
  ASSERT_EQ(first.exit_code, 0) << first.out;
  for (const auto& e : fs::directory_iterator(video))
    if (e.path().extension() != ".png") fs::remove(e.path());
  const auto run =
      test::run_command(cli() + " photo animate --in " + (in.dir.path / "photo.png").string() +
                            " --model " + (in.dir.path / "model.fbbm").string() + " --video " +
                            video.string() + " --out " + (in.dir.path / "from-video").string(),
                        test::Stderr::kDropped);
  ASSERT_EQ(run.exit_code, 0) << run.out;
  const auto j = nlohmann::json::parse(run.out);
  EXPECT_EQ(j["frames"], 4);
  EXPECT_EQ(j["video_frames_without_face"], 0);
  EXPECT_LT(j["video_joint_fit_error_px"].get<double>(), 3.0);
  EXPECT_GT(j["max_shift_px"].get<double>(), 2.0);  // the jaw the video opened
  EXPECT_TRUE(fs::exists(in.dir.path / "from-video" / "frame_0003.png"));
}

TEST(PhotoCli, EditChangesTheFaceLengthAndReportsIt) {
  Inputs in;
  const auto run = test::run_command(
      cli() + " photo edit --in " + (in.dir.path / "photo.png").string() + " --model " +
          (in.dir.path / "model.fbbm").string() + " --attribute face_length=+10mm --out " +
          (in.dir.path / "edited.png").string(),
      test::Stderr::kDropped);
  ASSERT_EQ(run.exit_code, 0) << run.out;
  const auto j = nlohmann::json::parse(run.out);
  EXPECT_NEAR(j["attributes_mm"]["face_length"]["change"].get<double>(), 10.0, 1.0);
  EXPECT_NEAR(j["attributes_mm"]["face_width"]["change"].get<double>(), 0.0, 1.0);
  EXPECT_TRUE(fs::exists(in.dir.path / "edited.png"));
}

TEST(PhotoCli, ErrorsSayWhatIsWrong) {
  TempDir dir;
  ColorImage blank;
  blank.resize(320, 240);
  std::fill(blank.pixels.begin(), blank.pixels.end(), Rgb8{128, 128, 128});
  ASSERT_TRUE(cli::write_photo(blank, dir.path / "blank.png").ok());
  const std::string base = cli() + " photo edit --in " + (dir.path / "blank.png").string() +
                           " --model none.fbbm --out " + (dir.path / "e.png").string();
  auto unknown = test::run_command(base + " --attribute chin_size=+3mm", test::Stderr::kMerged);
  EXPECT_NE(unknown.exit_code, 0);
  EXPECT_NE(unknown.out.find("unknown attribute 'chin_size'"), std::string::npos) << unknown.out;
  EXPECT_NE(unknown.out.find("face_length"), std::string::npos);  // lists the known ones
  auto bad = test::run_command(base + " --attribute face_length=tall", test::Stderr::kMerged);
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.out.find("not a change in millimetres"), std::string::npos) << bad.out;
  auto noface = test::run_command(base + " --attribute face_length=+5mm", test::Stderr::kMerged);
  EXPECT_NE(noface.exit_code, 0);
  EXPECT_NE(noface.out.find("no face found"), std::string::npos) << noface.out;
  auto help = test::run_command(cli() + " photo edit --help", test::Stderr::kMerged);
  for (const auto& a : default_attributes())
    EXPECT_NE(help.out.find(a.name), std::string::npos) << a.name;
}

}  // namespace
}  // namespace fb
