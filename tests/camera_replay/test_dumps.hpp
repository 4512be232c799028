// Test helpers shared by tests/camera_replay and tests/recorder: temporary directories, the real
// openiss-desk dump (extracted once per build tree), and small synthetic dumps.
#pragma once

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include "drivers/camera/common/fakenect_dump.hpp"

namespace fb::test {

// A fresh directory under the system temp dir, removed at scope exit.
class TempDir {
 public:
  explicit TempDir(const std::string& tag) {
    static std::atomic<int> counter{0};
    std::random_device rd;
    path_ = std::filesystem::temp_directory_path() /
            ("fb_" + tag + "_" + std::to_string(::getpid()) + "_" + std::to_string(counter++) +
             "_" + std::to_string(rd()));
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

inline std::string shell_quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

// The real Kinect dump shared/kinect/openiss-desk/test-recording-first90.tar.xz, extracted into
// <build>/test-data/openiss-desk once (atomically: extract to a private directory, then rename,
// so parallel test processes never see half a dump). Returns an empty path and sets `why` when
// the shared data is not available.
inline std::filesystem::path real_dump_dir(std::string& why) {
  namespace fs = std::filesystem;
  const fs::path archive =
      fs::path(FB_SHARED_DIR) / "kinect" / "openiss-desk" / "test-recording-first90.tar.xz";
  if (!fs::exists(archive)) {
    why = "real Kinect dump not found at " + archive.string() +
          " (FB_SHARED_DIR); configure with -DFB_SHARED_DIR=<shared dir> to run this test";
    return {};
  }
  const fs::path target = fs::path(FB_BINARY_DIR) / "test-data" / "openiss-desk";
  const fs::path dump = target / "test-recording-first90";
  if (fs::exists(dump / "INDEX.txt")) return dump;
  fs::create_directories(target.parent_path());
  // Parallel test processes (ctest -j) wait here for the first one instead of all extracting.
  const std::string lock_path = (target.parent_path() / "openiss-desk.lock").string();
  struct Lock {
    int fd;
    ~Lock() {
      if (fd >= 0) ::close(fd);  // closing releases the flock
    }
  } lock{::open(lock_path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644)};
  if (lock.fd >= 0) ::flock(lock.fd, LOCK_EX);
  if (fs::exists(dump / "INDEX.txt")) return dump;
  const fs::path tmp = target.parent_path() / ("openiss-desk.tmp-" + std::to_string(::getpid()));
  std::error_code ec;
  fs::remove_all(tmp, ec);
  fs::create_directories(tmp);
  const std::string cmd =
      "tar xJf " + shell_quote(archive.string()) + " -C " + shell_quote(tmp.string());
  if (std::system(cmd.c_str()) != 0) {
    fs::remove_all(tmp, ec);
    why = "could not extract " + archive.string() + " with `" + cmd + "` (is xz installed?)";
    return {};
  }
  fs::rename(tmp, target, ec);
  if (ec) fs::remove_all(tmp, ec);  // another process finished first; use its copy
  if (!fs::exists(dump / "INDEX.txt")) {
    why = "extracted " + archive.string() + " but " + dump.string() + "/INDEX.txt is missing";
    return {};
  }
  return dump;
}

// Deterministic test images.
inline DisparityImage test_disparity(int seed, int w = 640, int h = 480) {
  DisparityImage d;
  d.resize(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      d.at(x, y) = static_cast<std::uint16_t>(500 + (x + 3 * y + seed * 7) % 500);
  d.at(0, 0) = kInvalidDisparity;
  return d;
}
inline ColorImage test_color(int seed, int w = 640, int h = 480) {
  ColorImage c;
  c.resize(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      c.at(x, y) = Rgb8{static_cast<std::uint8_t>(x + seed), static_cast<std::uint8_t>(y),
                        static_cast<std::uint8_t>(seed)};
  return c;
}

inline void write_text(const std::filesystem::path& file, const std::string& text) {
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  out << text;
}

inline std::string read_text(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

}  // namespace fb::test
