// Progress for long work on stderr: a rewritten line on a terminal, and a line every ~10 %
// otherwise (logs and CI), so a pipe never fills with carriage returns.
#pragma once

#include <cstdint>
#include <map>
#include <mutex>
#include <string>

namespace fb::cli {

class Progress {
 public:
  Progress(std::string what, long long total);
  ~Progress();
  void update(long long done);

 private:
  std::string what_;
  long long total_;
  bool terminal_;
  long long last_reported_ = -1;
};

// A bar over bytes transferred by several workers at once (`sync`'s booths): each reports its
// own file's progress, the bar shows the sum. Thread-safe; on a terminal at most ~10 redraws a
// second, otherwise a line every ~10 % of what is known so far and one at the end.
class TransferProgress {
 public:
  explicit TransferProgress(std::string what);
  ~TransferProgress();
  // Worker `key` has `done` of `total` bytes of its current file (total 0: unknown yet).
  void update(const std::string& key, std::uint64_t done, std::uint64_t total);
  // Worker `key` finished its file (its bytes stay counted).
  void finish(const std::string& key);

 private:
  void draw(bool final);
  std::mutex mutex_;
  std::string what_;
  bool terminal_;
  struct Part {
    std::uint64_t done = 0, total = 0;
  };
  std::map<std::string, Part> active_;
  std::uint64_t finished_bytes_ = 0;
  std::uint64_t last_printed_ = 0;
  long long last_draw_ms_ = -1000;
  bool drawn_ = false;
};

}  // namespace fb::cli
