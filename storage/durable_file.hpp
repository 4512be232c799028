// Crash-safe file writing: data goes to a hidden temporary file in the target directory, is
// fsynced, renamed to its final name and the directory is fsynced. After a crash a reader sees
// either no file or the complete file under its final name, never a partial one; leftover
// temporaries are recognisable by their prefix (kDurableTempPrefix) and safe to delete.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <span>
#include <string>

#include "algo/core/result.hpp"
#include "storage/sha256.hpp"

namespace fb {

inline constexpr const char* kDurableTempPrefix = ".tmp-";

struct DurableFileHooks {
  // Called before each write(2) with the bytes written so far; non-zero = fail with this errno.
  std::function<int(std::size_t bytes_written)> inject_write_error;
  // Called when the writer enters a new step: 1 writing, 2 fsync, 3 rename.
  std::function<void(int step)> on_step;
};

// Owns an open file descriptor (RAII for the POSIX handle).
class UniqueFd {
 public:
  UniqueFd() = default;
  explicit UniqueFd(int fd) : fd_(fd) {}
  UniqueFd(UniqueFd&& o) noexcept : fd_(o.release()) {}
  UniqueFd& operator=(UniqueFd&& o) noexcept;
  ~UniqueFd();
  int get() const { return fd_; }
  int release() {
    const int fd = fd_;
    fd_ = -1;
    return fd;
  }
  bool valid() const { return fd_ >= 0; }
  // Closes now and reports close(2)'s error (NFS and some filesystems report write errors here).
  int close();

 private:
  int fd_ = -1;
};

class DurableFile {
 public:
  // Creates the temporary file next to `final_path`; the directory must exist.
  static Result<DurableFile> create(const std::filesystem::path& final_path,
                                    DurableFileHooks hooks = {});
  DurableFile(DurableFile&&) noexcept = default;
  DurableFile& operator=(DurableFile&&) noexcept = default;
  // Removes the temporary file unless commit() succeeded.
  ~DurableFile();

  Result<void> append(std::span<const std::uint8_t> bytes);
  Result<void> append(const void* data, std::size_t size) {
    return append({static_cast<const std::uint8_t*>(data), size});
  }
  // fsync, rename over the final name, fsync the directory. Afterwards the file is durable.
  Result<void> commit();

  std::uint64_t size() const { return size_; }
  const std::string& sha256() const { return digest_; }  // valid after commit()
  const std::filesystem::path& final_path() const { return final_path_; }

 private:
  DurableFile() = default;
  UniqueFd fd_;
  std::filesystem::path temp_path_;
  std::filesystem::path final_path_;
  DurableFileHooks hooks_;
  Sha256 hash_;
  std::string digest_;
  std::uint64_t size_ = 0;
  bool committed_ = false;
};

// Writes `bytes` durably to `path` (see DurableFile). Returns the SHA-256 hex digest.
Result<std::string> write_file_durably(const std::filesystem::path& path,
                                       std::span<const std::uint8_t> bytes,
                                       const DurableFileHooks& hooks = {});

// fsyncs a directory so that renames and creations inside it survive a power cut.
Result<void> fsync_directory(const std::filesystem::path& directory);

// Reads a whole file; errors name the file.
Result<std::vector<std::uint8_t>> read_file_bytes(const std::filesystem::path& path);

// SHA-256 of a file's contents (streamed).
Result<std::string> sha256_file(const std::filesystem::path& path);

// A random lowercase-hex token for unique file names (no shared generator state).
std::string random_token(int hex_chars = 12);

}  // namespace fb
