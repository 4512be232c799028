// Writes the seed corpora of the fuzz targets with the project's own writers (so they follow the
// formats as they change): `fuzz_seeds OUT_DIR` fills OUT_DIR/<target>/. Files the project
// ships (the guide recipes, the board's config) are added by path by scripts/fuzz.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "algo/bilinear/bilinear_model.hpp"
#include "algo/facemodel/face_model_format.hpp"
#include "drivers/camera/common/device_json.hpp"
#include "drivers/camera/common/fakenect_dump.hpp"
#include "firmware/daemon/daemon_config.hpp"
#include "storage/data_codec.hpp"
#include "storage/export/facewarehouse.hpp"
#include "storage/export/mesh_files.hpp"
#include "tests/common/bundle_writer.hpp"
#include "tests/common/tiny_face_model.hpp"

namespace {

namespace fs = std::filesystem;
using Bytes = std::string;

struct Corpus {
  fs::path dir;
  int count = 0;
  void add(const Bytes& content) {
    std::ofstream(dir / ("seed-" + std::to_string(count++)), std::ios::binary) << content;
  }
  // A selector byte, then the content.
  void add(char selector, const Bytes& content) { add(std::string(1, selector) + content); }
};

template <class Container>
Bytes as_bytes(const Container& c) {
  return Bytes(reinterpret_cast<const char*>(c.data()), c.size() * sizeof(c[0]));
}

fb::BilinearModel tiny_bilinear_model() {
  fb::BilinearModel m;
  m.vertex_count = 4;
  m.face_vertex_count = 3;
  m.id_knobs = 2;
  m.exp_knobs = 2;
  m.identity_count = 2;
  m.expression_count = 3;
  for (int i = 0; i < 3 * 4 * 2 * 2; ++i) m.core.push_back(0.5f * i - 3.0f);
  m.identity_factors = {1, 0, 0, 1};
  m.expression_factors = {1, 0, 0, 1, 0.5f, 0.5f};
  m.identity_spectrum = {2, 1};
  m.expression_spectrum = {3, 2, 1};
  m.expression_names = {"neutral", "jawOpen", "mouthSmile_L"};
  m.triangles = {0, 1, 2, 0, 2, 3};
  for (std::uint32_t i = 0; i < 68; ++i) m.landmark_vertices[i] = i % 4;
  m.metadata = "{\"source\": \"fuzz seed\"}";
  return m;
}

fb::RigData tiny_rig() {
  fb::RigData rig;
  rig.neutral = {0, 0, 0, 10, 0, 0, 0, 10, 0, 10, 10, 1};
  rig.shapes = {{0, 0, 1, 10, 0, 1, 0, 10, 1, 10, 10, 2}, {1, 0, 0, 11, 0, 0, 1, 10, 0, 11, 10, 1}};
  rig.shape_names = {"jawOpen", "mouthSmile_L"};
  rig.triangles = {0, 1, 2, 1, 3, 2};
  return rig;
}

void fakenect(Corpus c) {
  c.add('\0', "r-1.000000-1.ppm\na-1.000000-1.dump\nd-1.000000-1.pgm\nd-2.000000-2.pgm\n");
  c.add('\0', "d-1.000000-1.pgm\nr-1.000000-1.ppm\nd-2.000000-2.pgm\nd-2.0000");
  std::vector<std::uint8_t> bytes;
  fb::DisparityImage depth;
  depth.resize(4, 3);
  for (std::size_t i = 0; i < depth.pixels.size(); ++i)
    depth.pixels[i] = static_cast<std::uint16_t>(300 * i);
  fb::encode_depth_pgm(depth, bytes);
  c.add('\1', as_bytes(bytes));
  fb::ColorImage color;
  color.resize(3, 2);
  fb::encode_color_ppm(color, bytes);
  c.add('\2', as_bytes(bytes));
  c.add('\2', "P6\n# a comment\n2 1\n255\nabcdef");
  fb::encode_accel_dump(fb::AccelSample{12, -819, 40, -3, 1}, bytes);
  c.add('\3', as_bytes(bytes));
  std::string name;
  fb::format_dump_file_name(fb::DumpEntryType::kDepth, 1513096835.219278, 2320228015u, name);
  c.add('\4', name);
}

void store_files(Corpus c) {
  using namespace fb::store_detail;
  fb::RgbdFrame f;
  f.index = 3;
  f.depth_host_time_s = 1.5;
  f.depth_mm.resize(3, 2);
  f.raw_disparity.resize(3, 2);
  f.color.resize(2, 2);
  ByteWriter seq;
  seq.put_magic(kSeqMagic);
  seq.put(std::uint32_t{2});
  seq.put(std::uint32_t{0});
  for (int i = 0; i < 2; ++i) {
    (void)fb::frame_record::write(f, true, [&](const void* p, std::size_t n) -> fb::Result<void> {
      seq.bytes.insert(seq.bytes.end(), static_cast<const std::uint8_t*>(p),
                       static_cast<const std::uint8_t*>(p) + n);
      return fb::success();
    });
  }
  c.add('\0', as_bytes(seq.bytes));
  ByteWriter dep;
  dep.put_magic(kDepthMagic);
  dep.put(std::int32_t{2});
  dep.put(std::int32_t{2});
  dep.put_span(std::span<const std::uint16_t>(std::vector<std::uint16_t>{700, 701, 0, 702}));
  c.add('\1', as_bytes(dep.bytes));
  const fb::RigData rig = tiny_rig();
  ByteWriter mesh;
  mesh.put_magic(kMeshMagic);
  mesh.put(std::uint32_t(rig.vertex_count()));
  mesh.put(std::uint32_t(rig.triangles.size() / 3));
  mesh.put_span(std::span<const float>(rig.neutral));
  mesh.put_span(std::span<const std::uint32_t>(rig.triangles));
  c.add('\2', as_bytes(mesh.bytes));
  ByteWriter r;
  r.put_magic(kRigMagic);
  r.put(std::uint32_t(rig.vertex_count()));
  r.put(std::uint32_t(rig.triangles.size() / 3));
  r.put(std::uint32_t(rig.shapes.size()));
  r.put_span(std::span<const float>(rig.neutral));
  for (const auto& s : rig.shapes) r.put_span(std::span<const float>(s));
  r.put_span(std::span<const std::uint32_t>(rig.triangles));
  c.add('\3', as_bytes(r.bytes));
  const auto stride = static_cast<std::uint32_t>(fb::kTakePoseValues + 2);
  ByteWriter take;  // FBTAK002, 2 frames
  take.put_magic(kTakeMagic);
  take.put(std::uint32_t{2});
  take.put(stride);
  take.put_span(std::span<const double>(std::vector<double>{0.0, 0.033}));
  take.put_span(std::span<const float>(std::vector<float>(2 * stride, 0.25f)));
  c.add('\4', as_bytes(take.bytes));
  ByteWriter v1;  // FBTAK001 with the timestamp column
  v1.put_magic(kTakeMagicV1);
  v1.put(std::uint32_t{2});
  v1.put(stride + 1);
  v1.put_span(std::span<const float>(std::vector<float>(2 * (stride + 1), 0.5f)));
  c.add(static_cast<char>(0x85), as_bytes(v1.bytes));
}

void http(Corpus c) {
  c.add('\0',
        R"({"corrections": [{"index": 3, "u": 120.5, "v": 88}, {"index": 67, "u": 1, "v": 2}]})");
  c.add('\1', R"({"subject": "Ada"})");
  c.add('\1', "");
  c.add('\2', R"({"mode": "tracking"})");
  c.add('\3', R"({"frames": 45})");
  c.add('\4', R"({"button": "mode", "kind": "long"})");
  c.add('\5', "123456789012");
  c.add('\6', "jawOpen,mouthSmile_L,,browDown_L");
  fb::RigData rig = tiny_rig();
  const auto bs = fb::encode_shape_bs(rig);
  c.add('\7', std::string("\x13\x00", 2) + "jawOpen,mouthSmile_L" + as_bytes(bs));
  c.add('\7', std::string("\xff\xff", 2) + as_bytes(bs));
}

void facewarehouse(Corpus c) {
  const fb::RigData rig = tiny_rig();
  const auto bs = as_bytes(fb::encode_shape_bs(rig));
  const auto obj = fb::encode_obj(rig.neutral_mesh(), "fuzz seed");
  c.add('\0', bs);
  c.add('\1', obj);
  c.add('\1', "v 1 2 3\nv 4 5 6\nv 7 8 9\nv 1 1 1\nvt 0 0\nf 1/1/1 2/1/1 3/1/1 -1//1\n");
  const auto n = static_cast<std::uint32_t>(bs.size());
  c.add('\2', std::string(reinterpret_cast<const char*>(&n), 4) + bs + obj);
}

// Bundles a booth serves: a plain listing, a whole bundle with a capture, its session.json.
void bundles(Corpus c) {
  using fb::test::bundle;
  c.add('\0', fb::test::tar_entry("session-1/a.txt", "abc") + std::string(1024, '\0'));
  const std::string mesh = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  const std::string landmarks = R"({"source": "dlib", "points": [{"index": 0, "u": 1, "v": 2}]})";
  const std::string session = fb::test::session_json(nlohmann::json::array(
      {{{"index", 0}, {"expression", "neutral"}, {"state", "pending"}, {"attempts", 1}},
       {{"index", 1},
        {"expression", "smile"},
        {"state", "rejected"},
        {"qa", {{"coverage", 0.9}}},
        {"mesh", "m.obj"},
        {"landmarks", "l.json"}}}));
  c.add('\1', bundle({{"session-1/session.json", session, "session.json", session},
                      {"session-1/m.obj", mesh, "m.obj", mesh},
                      {"session-1/l.json", landmarks, "l.json", landmarks}}));
  c.add('\2', session);
  c.add('\2', fb::test::session_json());
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: fuzz_seeds OUT_DIR (writes OUT_DIR/<target>/seed-N)\n");
    return 2;
  }
  const fs::path out = argv[1];
  auto corpus = [&](const char* target) {
    fs::create_directories(out / target);
    return Corpus{out / target};
  };
  fakenect(corpus("fakenect_dump_fuzz"));
  {
    Corpus c = corpus("device_json_fuzz");
    auto calibration = fb::KinectCalibration::defaults();
    c.add(fb::to_device_json(calibration));
    calibration.correction.dx_px = 1.5;  // a calibrated unit: the "correction" object is written
    calibration.correction.rotation_deg = 0.2;
    c.add(fb::to_device_json(calibration));
  }
  {
    auto model = fb::serialize_face_model(fb::test::make_tiny_model());
    if (!model) {
      std::fprintf(stderr, "fuzz_seeds: %s\n", model.error().message.c_str());
      return 1;
    }
    corpus("face_model_fuzz").add(as_bytes(*model));
  }
  corpus("bilinear_model_fuzz").add(as_bytes(fb::serialize_bilinear_model(tiny_bilinear_model())));
  facewarehouse(corpus("facewarehouse_fuzz"));
  corpus("guide_fuzz");  // data/guide_expressions.json, added by path
  corpus("daemon_config_fuzz").add(fb::to_toml(fb::default_daemon_config()));
  http(corpus("http_requests_fuzz"));
  store_files(corpus("store_files_fuzz"));
  bundles(corpus("bundle_fuzz"));
  return 0;
}
