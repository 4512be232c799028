// Fakenect dump format: names, codecs, reader errors, writer behaviour. Synthetic data only.
#include <gtest/gtest.h>

#include "drivers/camera/common/device_json.hpp"
#include "drivers/camera/common/fakenect_dump.hpp"
#include "drivers/camera/replay/replay_camera.hpp"
#include "tests/camera_replay/test_dumps.hpp"
#include "tests/fuzz/regression_input.hpp"

namespace fb {
namespace {

using test::TempDir;
using test::write_text;

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

TEST(DumpFileName, ParsesFakenectNames) {
  auto d = parse_dump_file_name("d-1513096835.219278-2320228015.pgm");
  ASSERT_TRUE(d) << d.error().message;
  EXPECT_EQ(d->type, DumpEntryType::kDepth);
  EXPECT_DOUBLE_EQ(d->host_time_s, 1513096835.219278);
  EXPECT_EQ(d->device_timestamp, 2320228015u);
  auto r = parse_dump_file_name("r-1513096835.217482-2321038574.ppm");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->type, DumpEntryType::kColor);
  auto a = parse_dump_file_name("a-1513096835.222145-2320228015.dump");
  ASSERT_TRUE(a);
  EXPECT_EQ(a->type, DumpEntryType::kAccel);
}

TEST(DumpFileName, RejectsGarbage) {
  for (const char* bad : {"", "hello", "x-1.0-2.pgm", "d-1.0-2.ppm", "d-abc-2.pgm", "d-1.0-x.pgm",
                          "d-1.0-99999999999.pgm", "d-1.0.pgm", "d--1.0-2.pgm"}) {
    auto e = parse_dump_file_name(bad);
    ASSERT_FALSE(e) << bad;
    EXPECT_TRUE(contains(e.error().message, "not a fakenect dump file name")) << bad;
  }
}

// Found by fakenect_dump_fuzz: a host time of 1.5e18 s parsed, and formatting it back overflowed
// the microseconds (llround out of range) into a name that did not parse.
TEST(DumpFileName, RejectsHostTimesPastTheMicrosecondRange) {
  const std::string name =
      test::fuzz_regression("fakenect_dump_fuzz", "name-host-time-past-microseconds", true);
  ASSERT_EQ(name, "d-1513096721513096728-20228015.pgm");
  auto e = parse_dump_file_name(name);
  ASSERT_FALSE(e);
  EXPECT_TRUE(contains(e.error().message, "host time is out of range")) << e.error().message;
  std::string formatted;
  format_dump_file_name(DumpEntryType::kDepth, 1.5e18, 1, formatted);  // clamped, still a name
  EXPECT_TRUE(parse_dump_file_name(formatted)) << formatted;
}

TEST(DumpFileName, FormatRoundTrips) {
  std::string name;
  format_dump_file_name(DumpEntryType::kDepth, 1513096835.219278, 2320228015u, name);
  EXPECT_EQ(name, "d-1513096835.219278-2320228015.pgm");
  format_dump_file_name(DumpEntryType::kAccel, 0.5, 7, name);
  EXPECT_EQ(name, "a-0.500000-7.dump");
  format_dump_file_name(DumpEntryType::kColor, -3.0, 0, name);
  EXPECT_EQ(name, "r-0.000000-0.ppm");
}

TEST(DumpCodec, DepthIsLittleEndianLikeFakenect) {
  DisparityImage d;
  d.resize(2, 1);
  d.pixels = {0x03c6, 0x07ff};
  std::vector<std::uint8_t> bytes;
  encode_depth_pgm(d, bytes);
  const std::string header = "P5 2 1 65535\n";
  ASSERT_EQ(bytes.size(), header.size() + 4);
  EXPECT_EQ(std::string(bytes.begin(), bytes.begin() + header.size()), header);
  EXPECT_EQ(bytes[header.size()], 0xc6);
  EXPECT_EQ(bytes[header.size() + 1], 0x03);
}

class DumpFiles : public ::testing::Test {
 protected:
  TempDir dir{"dumpfiles"};
  std::vector<std::uint8_t> scratch;
  std::string file(const char* name) const { return (dir.path() / name).string(); }
};

TEST_F(DumpFiles, DepthCodecRoundTripAndBigEndianFallback) {
  const DisparityImage d = test::test_disparity(3);
  std::vector<std::uint8_t> bytes;
  encode_depth_pgm(d, bytes);
  write_text(file("le.pgm"), std::string(bytes.begin(), bytes.end()));
  DisparityImage back;
  ASSERT_TRUE(read_depth_pgm(file("le.pgm"), back, scratch));
  EXPECT_EQ(back.pixels, d.pixels);
  // A spec-conforming big-endian PGM is recognised too.
  const std::size_t h = bytes.size() - d.pixels.size() * 2;
  for (std::size_t i = h; i < bytes.size(); i += 2) std::swap(bytes[i], bytes[i + 1]);
  write_text(file("be.pgm"), std::string(bytes.begin(), bytes.end()));
  ASSERT_TRUE(read_depth_pgm(file("be.pgm"), back, scratch));
  EXPECT_EQ(back.pixels, d.pixels);
}

TEST_F(DumpFiles, BadDepthFiles) {
  const DisparityImage d = test::test_disparity(1, 4, 2);
  std::vector<std::uint8_t> bytes;
  encode_depth_pgm(d, bytes);
  const std::string good(bytes.begin(), bytes.end());
  DisparityImage out;
  const auto error = [&](const std::string& content) {
    write_text(file("x.pgm"), content);
    auto r = read_depth_pgm(file("x.pgm"), out, scratch);
    EXPECT_FALSE(r);
    return r ? std::string() : r.error().message;
  };
  EXPECT_TRUE(contains(error(good.substr(0, good.size() - 3)), "truncated"));
  EXPECT_TRUE(contains(error(""), "empty"));
  EXPECT_TRUE(contains(error("P5 4"), "malformed"));
  EXPECT_TRUE(contains(error("P6 4 2 65535\n" + good.substr(13)), "not a binary PGM"));
  EXPECT_TRUE(contains(error("P5 4 2 255\n" + good.substr(13)), "maxval 255"));
  EXPECT_TRUE(contains(error("P5 4 3 65535\n" + good.substr(13)), "truncated"));
  EXPECT_TRUE(contains(error("P5 4 1 65535\n" + good.substr(13)), "does not match"));
  EXPECT_TRUE(contains(error("P5 0 2 65535\n"), "implausible size"));
  std::string big = good;
  big[13] = '\xff';
  big[14] = '\xff';
  EXPECT_TRUE(contains(error(big), "above 2047"));
  auto missing = read_depth_pgm(file("nope.pgm"), out, scratch);
  ASSERT_FALSE(missing);
  EXPECT_TRUE(contains(missing.error().message, "nope.pgm"));
  // Comments in the header are allowed (netpbm).
  write_text(file("c.pgm"), "P5\n# comment\n4 2\n65535\n" + good.substr(13));
  ASSERT_TRUE(read_depth_pgm(file("c.pgm"), out, scratch));
  EXPECT_EQ(out.pixels, d.pixels);
}

TEST_F(DumpFiles, BadColorFiles) {
  const ColorImage c = test::test_color(1, 4, 2);
  std::vector<std::uint8_t> bytes;
  encode_color_ppm(c, bytes);
  const std::string good(bytes.begin(), bytes.end());
  ColorImage out;
  write_text(file("ok.ppm"), good);
  ASSERT_TRUE(read_color_ppm(file("ok.ppm"), out, scratch));
  EXPECT_EQ(out.width, 4);
  EXPECT_EQ(out.at(3, 1).r, c.at(3, 1).r);
  write_text(file("t.ppm"), good.substr(0, good.size() - 1));
  auto t = read_color_ppm(file("t.ppm"), out, scratch);
  ASSERT_FALSE(t);
  EXPECT_TRUE(contains(t.error().message, "truncated"));
  write_text(file("m.ppm"), "P6 4 2 65535\n" + good.substr(11));
  auto m = read_color_ppm(file("m.ppm"), out, scratch);
  ASSERT_FALSE(m);
  EXPECT_TRUE(contains(m.error().message, "maxval 65535"));
}

TEST_F(DumpFiles, AccelRoundTrip) {
  AccelSample s;
  s.accelerometer_x = 9;
  s.accelerometer_y = 814;
  s.accelerometer_z = -17;
  s.tilt_angle = -3;
  s.tilt_status = 4;
  std::vector<std::uint8_t> bytes;
  encode_accel_dump(s, bytes);
  ASSERT_EQ(bytes.size(), 12u);
  write_text(file("a.dump"), std::string(bytes.begin(), bytes.end()));
  auto back = read_accel_dump(file("a.dump"));
  ASSERT_TRUE(back) << back.error().message;
  EXPECT_EQ(back->accelerometer_y, 814);
  EXPECT_EQ(back->accelerometer_z, -17);
  EXPECT_EQ(back->tilt_angle, -3);
  EXPECT_EQ(back->tilt_status, 4);
  write_text(file("b.dump"), "short");
  EXPECT_FALSE(read_accel_dump(file("b.dump")));
}

// Writes a small valid dump: colour, depth, accel, depth, colour, depth.
void write_small_dump(const std::filesystem::path& dir) {
  auto w = FakenectDumpWriter::create(dir, KinectCalibration::defaults());
  ASSERT_TRUE(w) << w.error().message;
  ASSERT_TRUE(w->write_color(test::test_color(0), 10.0, 100));
  ASSERT_TRUE(w->write_depth(test::test_disparity(0), 10.01, 101));
  ASSERT_TRUE(w->write_accel(AccelSample{1, 819, 2, 0, 0}, 10.015, 101));
  ASSERT_TRUE(w->write_depth(test::test_disparity(1), 10.04, 102));
  ASSERT_TRUE(w->write_color(test::test_color(1), 10.05, 103));
  ASSERT_TRUE(w->write_depth(test::test_disparity(2), 10.07, 104));
  ASSERT_TRUE(w->finish());
}

TEST(DumpReader, ReadsWhatTheWriterWrote) {
  TempDir dir("rw");
  write_small_dump(dir.path());
  auto reader = FakenectDumpReader::open(dir.path());
  ASSERT_TRUE(reader) << reader.error().message;
  EXPECT_EQ(reader->entries().size(), 6u);
  EXPECT_EQ(reader->depth_frame_count(), 3u);
  EXPECT_EQ(reader->color_image_count(), 2u);
  ASSERT_TRUE(reader->device_calibration().has_value());
  RgbdFrame f;
  const int expected_color[] = {0, 0, 1};
  for (int i = 0; i < 3; ++i) {
    auto got = reader->next(f);
    ASSERT_TRUE(got) << got.error().message;
    ASSERT_TRUE(*got);
    EXPECT_EQ(f.index, static_cast<std::uint64_t>(i));
    EXPECT_EQ(f.raw_disparity.pixels, test::test_disparity(i).pixels);
    EXPECT_EQ(f.color.at(5, 5).r, test::test_color(expected_color[i]).at(5, 5).r);
    EXPECT_EQ(f.depth_device_timestamp, 101u + (i == 0 ? 0 : i == 1 ? 1 : 3));
    if (i > 0) {
      ASSERT_TRUE(reader->accel().has_value());
      EXPECT_EQ(reader->accel()->accelerometer_y, 819);
    } else {
      EXPECT_FALSE(reader->accel().has_value());
    }
  }
  EXPECT_NEAR(f.color_host_time_s, 10.05, 1e-6);
  auto end = reader->next(f);
  ASSERT_TRUE(end);
  EXPECT_FALSE(*end);
  reader->rewind();
  auto again = reader->next(f);
  ASSERT_TRUE(again && *again);
  EXPECT_EQ(f.index, 0u);
}

TEST(DumpReader, DepthBeforeAnyColourUsesFirstColour) {
  TempDir dir("early");
  {
    auto w = FakenectDumpWriter::create(dir.path(), KinectCalibration::defaults());
    ASSERT_TRUE(w);
    ASSERT_TRUE(w->write_depth(test::test_disparity(0), 1.0, 1));
    ASSERT_TRUE(w->write_color(test::test_color(7), 1.01, 2));
  }  // no finish(): the destructor leaves a valid dump
  auto reader = FakenectDumpReader::open(dir.path());
  ASSERT_TRUE(reader) << reader.error().message;
  RgbdFrame f;
  ASSERT_TRUE(*reader->next(f));
  EXPECT_EQ(f.color.at(0, 0).b, 7);
}

TEST(DumpReader, Errors) {
  TempDir dir("errors");
  const auto open_error = [](const std::filesystem::path& p) {
    auto r = FakenectDumpReader::open(p);
    EXPECT_FALSE(r);
    return r ? std::string() : r.error().message;
  };
  EXPECT_TRUE(contains(open_error(dir.path() / "missing"), "does not exist"));
  EXPECT_TRUE(contains(open_error(dir.path()), "no readable INDEX.txt"));
  write_text(dir.path() / "plain", "x");
  EXPECT_TRUE(contains(open_error(dir.path() / "plain"), "not a directory"));

  write_small_dump(dir.path() / "d");
  const auto index = dir.path() / "d" / "INDEX.txt";
  const std::string good_index = test::read_text(index);

  write_text(index, good_index + "this is garbage\n");
  const auto garbage = open_error(dir.path() / "d");
  EXPECT_TRUE(contains(garbage, "line 7")) << garbage;
  EXPECT_TRUE(contains(garbage, "this is garbage")) << garbage;

  write_text(index, good_index + "d-99.000000-1.pgm\n");
  EXPECT_TRUE(contains(open_error(dir.path() / "d"), "does not exist"));

  write_text(index, good_index + "../d-99.000000-1.pgm\n");
  EXPECT_FALSE(FakenectDumpReader::open(dir.path() / "d"));

  // An unterminated partial last line (interrupted writer) is ignored.
  write_text(index, good_index + "d-99.0");
  auto partial = FakenectDumpReader::open(dir.path() / "d");
  ASSERT_TRUE(partial) << partial.error().message;
  EXPECT_EQ(partial->depth_frame_count(), 3u);

  // CRLF line ends are fine.
  std::string crlf;
  for (char c : good_index) crlf += c == '\n' ? std::string("\r\n") : std::string(1, c);
  write_text(index, crlf);
  ASSERT_TRUE(FakenectDumpReader::open(dir.path() / "d"));

  write_text(index, good_index);
  write_text(dir.path() / "d" / "device.json", "{\"reg_info\": {}}");
  const auto json_error = open_error(dir.path() / "d");
  EXPECT_TRUE(contains(json_error, "reg_info.ax")) << json_error;
}

TEST(DumpReader, TruncatedImageFailsAtReadTime) {
  TempDir dir("trunc");
  write_small_dump(dir.path());
  auto reader = FakenectDumpReader::open(dir.path());
  ASSERT_TRUE(reader);
  const auto second_depth = dir.path() / reader->entries()[3].file_name;
  std::filesystem::resize_file(second_depth, 1000);
  RgbdFrame f;
  ASSERT_TRUE(*reader->next(f));
  auto bad = reader->next(f);
  ASSERT_FALSE(bad);
  EXPECT_TRUE(contains(bad.error().message, "truncated")) << bad.error().message;
  EXPECT_TRUE(contains(bad.error().message, reader->entries()[3].file_name));
}

TEST(DumpWriter, RefusesNonEmptyDirectoryUnlessOverwriting) {
  TempDir dir("refuse");
  write_text(dir.path() / "notes.txt", "keep me");
  auto refused = FakenectDumpWriter::create(dir.path(), KinectCalibration::defaults());
  ASSERT_FALSE(refused);
  EXPECT_TRUE(contains(refused.error().message, "not empty"));

  write_small_dump(dir.path() / "d");
  DumpWriterOptions overwrite;
  overwrite.overwrite = true;
  {
    auto w = FakenectDumpWriter::create(dir.path() / "d", KinectCalibration::defaults(), overwrite);
    ASSERT_TRUE(w) << w.error().message;
    ASSERT_TRUE(w->write_depth(test::test_disparity(5), 1.0, 1));
  }
  auto reader = FakenectDumpReader::open(dir.path() / "d");
  ASSERT_TRUE(reader);
  EXPECT_EQ(reader->entries().size(), 1u);
  // Old d-/r-/a- files are gone.
  int files = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir.path() / "d"))
    files += !!e.is_regular_file();
  EXPECT_EQ(files, 3);  // INDEX.txt, device.json, one depth image
  EXPECT_TRUE(std::filesystem::exists(dir.path() / "notes.txt"));
}

TEST(DumpWriter, InterruptedRecordingIsAValidShorterDump) {
  TempDir dir("interrupt");
  auto w = FakenectDumpWriter::create(dir.path(), KinectCalibration::defaults());
  ASSERT_TRUE(w);
  ASSERT_TRUE(w->write_depth(test::test_disparity(0), 1.0, 1));
  ASSERT_TRUE(w->write_depth(test::test_disparity(1), 1.033, 2));
  // Simulate a crash while the third image was being written: a partial file without its line.
  write_text(dir.path() / "d-1.066000-3.pgm", "P5 640 480 65535\n\x01\x02");
  // INDEX.txt is complete up to the last finished entry even before finish().
  auto reader = FakenectDumpReader::open(dir.path());
  ASSERT_TRUE(reader) << reader.error().message;
  EXPECT_EQ(reader->depth_frame_count(), 2u);
  RgbdFrame f;
  ASSERT_TRUE(*reader->next(f));
  ASSERT_TRUE(*reader->next(f));
  EXPECT_EQ(f.raw_disparity.pixels, test::test_disparity(1).pixels);
}

TEST(DumpWriter, KeepsNamesUniqueAndOrdered) {
  TempDir dir("unique");
  auto w = FakenectDumpWriter::create(dir.path(), KinectCalibration::defaults());
  ASSERT_TRUE(w);
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(w->write_depth(test::test_disparity(i), 0.0, 0));
  ASSERT_TRUE(w->finish());
  EXPECT_FALSE(w->write_depth(test::test_disparity(0), 5.0, 0));
  EXPECT_EQ(test::read_text(dir.path() / "INDEX.txt"),
            "d-0.000000-0.pgm\nd-0.000001-0.pgm\nd-0.000002-0.pgm\n");
}

TEST(ReplayUri, BadArguments) {
  const auto backend = replay_camera_backend();
  EXPECT_EQ(backend.name, "replay");
  auto empty = backend.open("");
  ASSERT_FALSE(empty);
  EXPECT_TRUE(contains(empty.error().message, "replay:DIR"));
  auto missing = backend.open("/nonexistent/dump");
  ASSERT_FALSE(missing);
  EXPECT_TRUE(contains(missing.error().message, "does not exist"));
  auto bad_option = backend.open("/nonexistent/dump,speed=2");
  ASSERT_FALSE(bad_option);
  EXPECT_TRUE(contains(bad_option.error().message, "unknown replay option 'speed'"));
  TempDir dir("emptydump");
  write_text(dir.path() / "INDEX.txt", "");
  auto no_frames = backend.open(dir.path().string());
  ASSERT_FALSE(no_frames);
  EXPECT_TRUE(contains(no_frames.error().message, "no depth frames"));
  EXPECT_TRUE(backend.list().empty());
}

TEST(ReplayCamera, SyntheticDumpWithLoopAndDefaultsCalibration) {
  TempDir dir("loop");
  write_small_dump(dir.path());
  std::filesystem::remove(dir.path() / "device.json");
  auto cam = replay_camera_backend().open(dir.path().string() + ",loop=1");
  ASSERT_TRUE(cam) << cam.error().message;
  auto& camera = **cam;
  EXPECT_EQ(camera.info().frame_count, -1);
  EXPECT_TRUE(contains(camera.info().description, "defaults"));
  RgbdFrame f;
  auto not_started = camera.next_frame(f, std::chrono::milliseconds(0));
  EXPECT_FALSE(not_started);
  ASSERT_TRUE(camera.start());
  const KinectRegistration reg(KinectCalibration::typical_unit());
  EXPECT_DOUBLE_EQ(camera.info().calibration.correction.dy_px, -13.0);
  for (int i = 0; i < 7; ++i) {
    auto s = camera.next_frame(f, std::chrono::milliseconds(100));
    ASSERT_TRUE(s) << s.error().message;
    ASSERT_EQ(*s, FrameStatus::kFrame);
    EXPECT_EQ(f.index, static_cast<std::uint64_t>(i));
    EXPECT_EQ(f.raw_disparity.pixels, test::test_disparity(i % 3).pixels);
    EXPECT_EQ(f.depth_mm.at(10, 10), reg.raw_to_mm(f.raw_disparity.at(10, 10)));
  }
}

}  // namespace
}  // namespace fb
