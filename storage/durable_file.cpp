#include "storage/durable_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <random>
#include <vector>

namespace fb {
namespace {

std::string errno_text(int err) {
  return std::strerror(err);
}

std::string write_error_message(int err, const std::filesystem::path& path, std::uint64_t done) {
  if (err == ENOSPC || err == EDQUOT) {
    return "no space left on the disk holding " + path.parent_path().string() + " while writing " +
           path.filename().string() + " (" + std::to_string(done) +
           " bytes written): free space (remove old exports or sessions) and retry; nothing "
           "already stored was changed";
  }
  return "cannot write " + path.string() + ": " + errno_text(err) +
         " (check the disk and its permissions, then retry; nothing already stored was changed)";
}

}  // namespace

UniqueFd& UniqueFd::operator=(UniqueFd&& o) noexcept {
  if (this != &o) {
    close();
    fd_ = o.release();
  }
  return *this;
}

UniqueFd::~UniqueFd() {
  close();
}

int UniqueFd::close() {
  if (fd_ < 0) return 0;
  const int rc = ::close(fd_);
  fd_ = -1;
  return rc == 0 ? 0 : errno;
}

std::string random_token(int hex_chars) {
  std::random_device device;
  std::mt19937_64 rng((static_cast<std::uint64_t>(device()) << 32) ^ device() ^
                      static_cast<std::uint64_t>(::getpid()));
  static constexpr char kHex[] = "0123456789abcdef";
  std::string s;
  for (int i = 0; i < hex_chars; ++i) s.push_back(kHex[rng() & 0xf]);
  return s;
}

Result<DurableFile> DurableFile::create(const std::filesystem::path& final_path,
                                        DurableFileHooks hooks) {
  DurableFile file;
  file.final_path_ = final_path;
  file.hooks_ = std::move(hooks);
  file.temp_path_ =
      final_path.parent_path() /
      (std::string(kDurableTempPrefix) + final_path.filename().string() + "-" + random_token());
  const int fd = ::open(file.temp_path_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd < 0) {
    const int err = errno;
    if (err == ENOENT) {
      return fail("cannot create a file in " + final_path.parent_path().string() +
                  ": the folder does not exist (restore it from a backup, or check the store "
                  "path)");
    }
    return fail(write_error_message(err, final_path, 0));
  }
  file.fd_ = UniqueFd(fd);
  if (file.hooks_.on_step) file.hooks_.on_step(1);
  return file;
}

DurableFile::~DurableFile() {
  if (!committed_ && !temp_path_.empty()) {
    fd_.close();
    ::unlink(temp_path_.c_str());
  }
}

Result<void> DurableFile::append(std::span<const std::uint8_t> bytes) {
  if (!fd_.valid()) return fail("internal: append to a closed file " + final_path_.string());
  hash_.update(bytes);
  const std::uint8_t* p = bytes.data();
  std::size_t left = bytes.size();
  while (left > 0) {
    if (hooks_.inject_write_error) {
      if (const int err = hooks_.inject_write_error(size_); err != 0) {
        return fail(write_error_message(err, final_path_, size_));
      }
    }
    const ssize_t n = ::write(fd_.get(), p, left);
    if (n < 0) {
      if (errno == EINTR) continue;
      return fail(write_error_message(errno, final_path_, size_));
    }
    p += n;
    left -= static_cast<std::size_t>(n);
    size_ += static_cast<std::uint64_t>(n);
  }
  return success();
}

Result<void> DurableFile::commit() {
  if (!fd_.valid()) return fail("internal: commit of a closed file " + final_path_.string());
  if (hooks_.on_step) hooks_.on_step(2);
  if (::fsync(fd_.get()) != 0) return fail(write_error_message(errno, final_path_, size_));
  if (const int err = fd_.close(); err != 0)
    return fail(write_error_message(err, final_path_, size_));
  if (hooks_.on_step) hooks_.on_step(3);
  if (::rename(temp_path_.c_str(), final_path_.c_str()) != 0) {
    return fail("cannot rename " + temp_path_.string() + " to " + final_path_.filename().string() +
                ": " + errno_text(errno));
  }
  committed_ = true;
  digest_ = hash_.hex_digest();
  if (auto synced = fsync_directory(final_path_.parent_path()); !synced) return synced;
  return success();
}

Result<std::string> write_file_durably(const std::filesystem::path& path,
                                       std::span<const std::uint8_t> bytes,
                                       const DurableFileHooks& hooks) {
  auto file = DurableFile::create(path, hooks);
  if (!file) return file.failure();
  if (auto r = file->append(bytes); !r) return r.failure();
  if (auto r = file->commit(); !r) return r.failure();
  return file->sha256();
}

Result<void> fsync_directory(const std::filesystem::path& directory) {
  UniqueFd fd(::open(directory.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC));
  if (!fd.valid())
    return fail("cannot open folder " + directory.string() + ": " + errno_text(errno));
  if (::fsync(fd.get()) != 0) {
    return fail("cannot sync folder " + directory.string() + ": " + errno_text(errno));
  }
  return success();
}

Result<std::vector<std::uint8_t>> read_file_bytes(const std::filesystem::path& path) {
  UniqueFd fd(::open(path.c_str(), O_RDONLY | O_CLOEXEC));
  if (!fd.valid()) return fail("cannot open " + path.string() + ": " + errno_text(errno));
  struct stat st {};
  if (::fstat(fd.get(), &st) != 0) return fail("cannot stat " + path.string());
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(st.st_size));
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::read(fd.get(), bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) return fail("cannot read " + path.string() + ": " + errno_text(errno));
    if (n == 0) break;
    done += static_cast<std::size_t>(n);
  }
  bytes.resize(done);
  return bytes;
}

Result<std::string> sha256_file(const std::filesystem::path& path) {
  UniqueFd fd(::open(path.c_str(), O_RDONLY | O_CLOEXEC));
  if (!fd.valid()) return fail("cannot open " + path.string() + ": " + errno_text(errno));
  Sha256 hash;
  std::vector<std::uint8_t> buffer(1 << 20);
  for (;;) {
    const ssize_t n = ::read(fd.get(), buffer.data(), buffer.size());
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) return fail("cannot read " + path.string() + ": " + errno_text(errno));
    if (n == 0) break;
    hash.update({buffer.data(), static_cast<std::size_t>(n)});
  }
  return hash.hex_digest();
}

}  // namespace fb
