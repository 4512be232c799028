// Small file helpers shared by the SessionRecords implementations: durable writes
// (temp + fsync + rename + directory fsync), 16-bit PGM and PPM encoding, UTC timestamps.
#pragma once

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <string>

#include "algo/core/image.hpp"
#include "algo/core/result.hpp"

namespace fb::records {
namespace fs = std::filesystem;

// Owns a file descriptor (RAII for the C handle).
class Fd {
 public:
  explicit Fd(int fd) : fd_(fd) {}
  ~Fd() {
    if (fd_ >= 0) ::close(fd_);
  }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  int get() const { return fd_; }

 private:
  int fd_;
};

inline std::string now_iso() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

inline Result<void> write_durable(const fs::path& path, const std::string& bytes) {
  const fs::path tmp = path.string() + ".tmp";
  {
    Fd fd(::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644));
    if (fd.get() < 0) return fail("cannot write '" + tmp.string() + "': " + std::strerror(errno));
    std::size_t done = 0;
    while (done < bytes.size()) {
      const ssize_t n = ::write(fd.get(), bytes.data() + done, bytes.size() - done);
      if (n < 0) {
        if (errno == EINTR) continue;
        return fail("writing '" + tmp.string() + "' failed: " + std::strerror(errno));
      }
      done += static_cast<std::size_t>(n);
    }
    if (::fsync(fd.get()) != 0) return fail("fsync of '" + tmp.string() + "' failed");
  }
  if (::rename(tmp.c_str(), path.c_str()) != 0)
    return fail("cannot rename '" + tmp.string() + "': " + std::strerror(errno));
  Fd dir(::open(path.parent_path().c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC));
  if (dir.get() >= 0) ::fsync(dir.get());
  return success();
}

inline std::string pgm16(const DepthImage& image) {
  std::string out =
      "P5\n" + std::to_string(image.width) + " " + std::to_string(image.height) + "\n65535\n";
  out.reserve(out.size() + image.pixels.size() * 2);
  for (std::uint16_t v : image.pixels) {
    out.push_back(static_cast<char>(v >> 8));
    out.push_back(static_cast<char>(v & 0xff));
  }
  return out;
}

inline std::string ppm(const ColorImage& image) {
  std::string out =
      "P6\n" + std::to_string(image.width) + " " + std::to_string(image.height) + "\n255\n";
  for (const Rgb8& p : image.pixels) {
    out.push_back(static_cast<char>(p.r));
    out.push_back(static_cast<char>(p.g));
    out.push_back(static_cast<char>(p.b));
  }
  return out;
}

}  // namespace fb::records
