// Runs a shell command (the facebooth binary, a Debian tool) from a test and collects its exit
// code and output.
#pragma once

#include <sys/wait.h>

#include <cstdio>
#include <memory>
#include <string>

namespace fb::test {

struct CommandRun {
  int exit_code = -1;  // -1: could not start, or killed by a signal
  std::string out;
};

enum class Stderr {
  kMerged,   // into `out`, interleaved with stdout as a terminal shows them
  kToLog,    // left on the test's stderr (the CTest log)
  kDropped,  // discarded: `out` is exactly what a JSON printer wrote
};

inline CommandRun run_command(const std::string& command, Stderr err) {
  const char* redirect = err == Stderr::kMerged    ? " 2>&1"
                         : err == Stderr::kDropped ? " 2>/dev/null"
                                                   : "";
  CommandRun run;
  std::unique_ptr<FILE, int (*)(FILE*)> pipe(::popen((command + redirect).c_str(), "r"), ::pclose);
  if (!pipe) return run;
  char buf[4096];
  for (std::size_t n; (n = std::fread(buf, 1, sizeof buf, pipe.get())) > 0;) run.out.append(buf, n);
  const int status = ::pclose(pipe.release());
  run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return run;
}

}  // namespace fb::test
