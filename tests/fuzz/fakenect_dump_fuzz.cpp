// fakenect dumps (drivers/camera/common/fakenect_dump): INDEX.txt, the d-/r-/a- frame files and
// their names. The first byte picks the part, the rest is its content.
#include "drivers/camera/common/fakenect_dump.hpp"
#include "tests/fuzz/fuzz_util.hpp"

namespace {

// A dump folder holding one small frame file of each kind, for INDEX.txt inputs to list.
const std::filesystem::path& dump_dir() {
  static const std::filesystem::path dir = [] {
    const auto d = fb::fuzz::scratch_dir() / "dump";
    std::filesystem::create_directories(d);
    std::vector<std::uint8_t> bytes;
    fb::DisparityImage depth;
    depth.resize(4, 3);
    for (std::size_t i = 0; i < depth.pixels.size(); ++i)
      depth.pixels[i] = static_cast<std::uint16_t>(400 + 50 * i);
    fb::encode_depth_pgm(depth, bytes);
    for (const char* name : {"d-1.000000-1.pgm", "d-2.000000-2.pgm"})
      fb::fuzz::write_file(d / name, {reinterpret_cast<const char*>(bytes.data()), bytes.size()});
    fb::ColorImage color;
    color.resize(4, 3);
    fb::encode_color_ppm(color, bytes);
    fb::fuzz::write_file(d / "r-1.000000-1.ppm",
                         {reinterpret_cast<const char*>(bytes.data()), bytes.size()});
    fb::encode_accel_dump(fb::AccelSample{1, -819, 3, 4, 0}, bytes);
    fb::fuzz::write_file(d / "a-1.000000-1.dump",
                         {reinterpret_cast<const char*>(bytes.data()), bytes.size()});
    return d;
  }();
  return dir;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const std::string_view body = fb::fuzz::text(data + 1, size - 1);
  const auto file = fb::fuzz::scratch_dir() / "frame";
  std::vector<std::uint8_t> scratch;
  switch (data[0] % 5) {
    case 0: {
      fb::fuzz::write_file(dump_dir() / fb::kDumpIndexFileName, body);
      auto reader = fb::FakenectDumpReader::open(dump_dir());
      if (!reader) break;
      fb::RgbdFrame frame;
      for (int i = 0; i < 16; ++i) {
        auto more = reader->next(frame);
        if (!more || !*more) break;
      }
      break;
    }
    case 1: {
      fb::fuzz::write_file(file, body);
      fb::DisparityImage depth;
      if (fb::read_depth_pgm(file.string(), depth, scratch))
        fb::fuzz::require(depth.pixels.size() == std::size_t(depth.width) * depth.height,
                          "depth size matches its header");
      break;
    }
    case 2: {
      fb::fuzz::write_file(file, body);
      fb::ColorImage color;
      (void)fb::read_color_ppm(file.string(), color, scratch);
      break;
    }
    case 3: {
      fb::fuzz::write_file(file, body);
      (void)fb::read_accel_dump(file.string(), scratch);
      break;
    }
    default: {
      auto entry = fb::parse_dump_file_name(body);
      if (entry) {
        std::string name;
        fb::format_dump_file_name(entry->type, entry->host_time_s, entry->device_timestamp, name);
        fb::fuzz::require(fb::parse_dump_file_name(name).ok(), "a formatted name parses");
      }
      break;
    }
  }
  return 0;
}
