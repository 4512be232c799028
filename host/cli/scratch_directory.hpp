// A scratch directory for an eval or bench run, removed with everything in it when the run
// ends (unless kept), so an interrupted or failed run leaves nothing behind.
#pragma once

#include <filesystem>
#include <string>
#include <system_error>
#include <utility>

#include "algo/core/result.hpp"
#include "storage/durable_file.hpp"

namespace fb::cli {

class ScratchDirectory {
 public:
  // Creates parent / (prefix + a random token); parent empty: the temp folder.
  static Result<ScratchDirectory> create(const std::string& prefix,
                                         const std::filesystem::path& parent = {},
                                         bool keep = false) {
    const std::filesystem::path base =
        parent.empty() ? std::filesystem::temp_directory_path() : parent;
    ScratchDirectory dir(base / (prefix + random_token(12)), keep);
    std::error_code ec;
    std::filesystem::create_directories(dir.path_, ec);
    if (ec) {
      const std::string message = "cannot create the scratch folder " + dir.path_.string() + ": " +
                                  ec.message() + " (it needs a writable folder with free space)";
      dir.path_.clear();  // nothing of ours to remove
      return fail(message);
    }
    return dir;
  }
  ScratchDirectory(ScratchDirectory&& other) noexcept
      : path_(std::exchange(other.path_, {})), keep_(other.keep_) {}
  ScratchDirectory& operator=(ScratchDirectory&&) = delete;
  ScratchDirectory(const ScratchDirectory&) = delete;
  ~ScratchDirectory() {
    if (keep_ || path_.empty()) return;
    std::error_code ignored;
    std::filesystem::remove_all(path_, ignored);
  }
  const std::filesystem::path& path() const { return path_; }

 private:
  ScratchDirectory(std::filesystem::path path, bool keep) : path_(std::move(path)), keep_(keep) {}
  std::filesystem::path path_;
  bool keep_ = false;
};

}  // namespace fb::cli
