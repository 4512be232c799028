#include "host/cli/progress.hpp"

#include <unistd.h>

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

}  // namespace fb::cli
