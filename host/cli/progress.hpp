// Progress for long work on stderr: a rewritten line on a terminal, and a line every ~10 %
// otherwise (logs and CI), so a pipe never fills with carriage returns.
#pragma once

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

}  // namespace fb::cli
