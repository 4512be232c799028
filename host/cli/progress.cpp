#include "host/cli/progress.hpp"

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <iostream>

namespace fb::cli {

Progress::Progress(std::string what, long long total)
    : what_(std::move(what)), total_(total), terminal_(::isatty(STDERR_FILENO) == 1) {}

Progress::~Progress() {
  if (terminal_ && last_reported_ >= 0) std::cerr << "\n";
}

void Progress::update(long long done) {
  if (terminal_) {
    std::cerr << "\r" << what_ << " " << done << "/" << total_ << std::flush;
    last_reported_ = done;
    return;
  }
  const long long step = total_ >= 10 ? total_ / 10 : 1;
  if (done == total_ || done / step != last_reported_ / step) {
    std::cerr << what_ << " " << done << "/" << total_ << "\n";
    last_reported_ = done;
  }
}

TransferProgress::TransferProgress(std::string what)
    : what_(std::move(what)), terminal_(::isatty(STDERR_FILENO) == 1) {}

TransferProgress::~TransferProgress() {
  std::lock_guard lock(mutex_);
  if (drawn_) draw(true);
  if (terminal_ && drawn_) std::cerr << "\n";
}

void TransferProgress::update(const std::string& key, std::uint64_t done, std::uint64_t total) {
  std::lock_guard lock(mutex_);
  active_[key] = {done, total};
  draw(false);
}

void TransferProgress::finish(const std::string& key) {
  std::lock_guard lock(mutex_);
  if (auto it = active_.find(key); it != active_.end()) {
    finished_bytes_ += it->second.done;
    active_.erase(it);
  }
  draw(false);
}

void TransferProgress::draw(bool final) {
  std::uint64_t done = finished_bytes_, total = finished_bytes_;
  for (const auto& [key, p] : active_) {
    done += p.done;
    total += std::max(p.total, p.done);
  }
  const long long now_ms = std::chrono::duration_cast<std::chrono::milliseconds>(
                               std::chrono::steady_clock::now().time_since_epoch())
                               .count();
  // MB, or kB for what is smaller than a megabyte (a refused bundle, a tiny session).
  const bool small = total < 1'000'000;
  const double mb = small ? 1e3 : 1e6;
  const char* unit = small ? "kB" : "MB";
  char line[160];
  if (terminal_) {
    if (!final && now_ms - last_draw_ms_ < 100) return;
    const int width = 30;
    const int filled = total > 0 ? static_cast<int>(width * static_cast<double>(done) / total) : 0;
    std::string bar(static_cast<std::size_t>(filled), '#');
    bar.resize(width, '.');
    std::snprintf(line, sizeof line, "\r%s [%s] %6.1f / %.1f %s", what_.c_str(), bar.c_str(),
                  done / mb, total / mb, unit);
    std::cerr << line << std::flush;
  } else {
    // Logs: a line per ~10 % of what is known so far, and the last one.
    if (!final && done < last_printed_ + std::max<std::uint64_t>(total / 10, 1)) return;
    std::snprintf(line, sizeof line, "%s %.1f / %.1f %s\n", what_.c_str(), done / mb, total / mb,
                  unit);
    std::cerr << line;
    last_printed_ = done;
  }
  last_draw_ms_ = now_ms;
  drawn_ = true;
}

}  // namespace fb::cli
