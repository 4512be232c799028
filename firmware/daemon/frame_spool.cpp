#include "firmware/daemon/frame_spool.hpp"

#include <unistd.h>

#include <random>
#include <system_error>

namespace fb {
namespace fs = std::filesystem;

namespace {
constexpr const char* kPrefix = "take-";
constexpr const char* kSuffix = ".spool";
}  // namespace

FrameSpool::FrameSpool(fs::path path, std::fstream file)
    : path_(std::move(path)), file_(std::move(file)) {}

FrameSpool::~FrameSpool() {
  file_.close();
  std::error_code ec;
  fs::remove(path_, ec);
}

Result<std::unique_ptr<FrameSpool>> FrameSpool::create(const fs::path& folder) {
  std::error_code ec;
  fs::create_directories(folder, ec);
  if (ec)
    return fail("cannot create the frame spool folder " + folder.string() + ": " + ec.message() +
                "; check [storage] data_dir and its permissions");
  std::random_device random;  // unique among the takes of this process and others
  const fs::path path =
      folder / (kPrefix + std::to_string(::getpid()) + "-" + std::to_string(random()) + kSuffix);
  std::fstream file(path, std::ios::binary | std::ios::in | std::ios::out | std::ios::trunc);
  if (!file.is_open())
    return fail("cannot create the frame spool file " + path.string() +
                "; check free space and permissions of [storage] data_dir");
  return std::unique_ptr<FrameSpool>(new FrameSpool(path, std::move(file)));
}

void FrameSpool::remove_stale(const fs::path& folder) {
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(folder, ec)) {
    const std::string name = e.path().filename().string();
    if (name.rfind(kPrefix, 0) == 0 && e.path().extension() == kSuffix) fs::remove(e.path(), ec);
  }
}

Result<void> FrameSpool::append(const RgbdFrame& f) {
  Record r{end_,
           f.index,
           f.depth_host_time_s,
           f.color_host_time_s,
           f.depth_device_timestamp,
           f.color_device_timestamp,
           f.depth_mm.width,
           f.depth_mm.height,
           f.color.width,
           f.color.height};
  const auto depth_bytes = f.depth_mm.pixels.size() * sizeof(f.depth_mm.pixels[0]);
  const auto color_bytes = f.color.pixels.size() * sizeof(f.color.pixels[0]);
  file_.seekp(static_cast<std::streamoff>(end_));
  file_.write(reinterpret_cast<const char*>(f.depth_mm.pixels.data()),
              static_cast<std::streamsize>(depth_bytes));
  file_.write(reinterpret_cast<const char*>(f.color.pixels.data()),
              static_cast<std::streamsize>(color_bytes));
  if (!file_) {
    file_.clear();
    return fail("cannot write the take's frames to " + path_.string() + " (disk full?)");
  }
  end_ += depth_bytes + color_bytes;
  records_.push_back(r);
  return success();
}

Result<void> FrameSpool::read(std::size_t i, RgbdFrame& out) {
  if (i >= records_.size()) return fail("frame " + std::to_string(i) + " is not in the spool");
  const Record& r = records_[i];
  out.index = r.index;
  out.depth_host_time_s = r.depth_host_time_s;
  out.color_host_time_s = r.color_host_time_s;
  out.depth_device_timestamp = r.depth_device_timestamp;
  out.color_device_timestamp = r.color_device_timestamp;
  out.raw_disparity = {};
  out.depth_mm.resize(r.depth_w, r.depth_h);
  out.color.resize(r.color_w, r.color_h);
  file_.flush();
  file_.seekg(static_cast<std::streamoff>(r.offset));
  file_.read(
      reinterpret_cast<char*>(out.depth_mm.pixels.data()),
      static_cast<std::streamsize>(out.depth_mm.pixels.size() * sizeof(out.depth_mm.pixels[0])));
  file_.read(reinterpret_cast<char*>(out.color.pixels.data()),
             static_cast<std::streamsize>(out.color.pixels.size() * sizeof(out.color.pixels[0])));
  if (!file_) {
    file_.clear();
    return fail("cannot read frame " + std::to_string(i) + " back from " + path_.string());
  }
  return success();
}

}  // namespace fb
