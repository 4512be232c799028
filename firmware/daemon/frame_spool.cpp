#include "firmware/daemon/frame_spool.hpp"

#include <unistd.h>

#include <random>
#include <system_error>

#include "storage/frame_record.hpp"

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
  file_.seekp(static_cast<std::streamoff>(end_));
  auto sink = [&](const void* data, std::size_t size) -> Result<void> {
    file_.write(static_cast<const char*>(data), static_cast<std::streamsize>(size));
    if (file_) return success();
    file_.clear();
    return fail("cannot write the take's frames to " + path_.string() + " (disk full?)");
  };
  if (auto r = frame_record::write(f, /*with_raw_disparity=*/false, sink); !r) return r;
  offsets_.push_back(end_);
  end_ += sizeof(frame_record::Header) +
          frame_record::pixel_bytes(frame_record::header_of(f, /*with_raw_disparity=*/false));
  return success();
}

Result<void> FrameSpool::read(std::size_t i, RgbdFrame& out) {
  if (i >= offsets_.size()) return fail("frame " + std::to_string(i) + " is not in the spool");
  file_.flush();
  file_.seekg(static_cast<std::streamoff>(offsets_[i]));
  auto source = [&](void* data, std::size_t size) {
    return static_cast<bool>(
        file_.read(static_cast<char*>(data), static_cast<std::streamsize>(size)));
  };
  frame_record::Header h{};
  if (!source(&h, sizeof h) || !frame_record::plausible(h) ||
      !frame_record::read_pixels(h, out, source)) {
    file_.clear();
    return fail("cannot read frame " + std::to_string(i) + " back from " + path_.string());
  }
  return success();
}

}  // namespace fb
