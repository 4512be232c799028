// A stand-alone front end for the tracking commands only (`eval track`, `bench track`, `track`),
// the same code as in `facebooth`, so the tracking figures can be produced even when another
// area keeps the full CLI from linking. Usage: facebooth-track eval track --json
#include <iostream>
#include <string>
#include <vector>

#include "host/cli/commands.hpp"

namespace fb::cli {
int report_failure(const Error& error) {
  std::cerr << "facebooth: " << error.message << "\n";
  return kExitFailure;
}
}  // namespace fb::cli

int main(int argc, char** argv) {
  using namespace fb::cli;
  const std::vector<std::string> args(argv + 1, argv + argc);
  for (const auto& command : tracking_commands()) {
    const std::string& path = command.spec.path;
    const auto space = path.find(' ');
    std::size_t consumed = 0;
    if (space == std::string::npos && !args.empty() && args[0] == path) consumed = 1;
    if (space != std::string::npos && args.size() >= 2 && args[0] == path.substr(0, space) &&
        args[1] == path.substr(space + 1)) {
      consumed = 2;
    }
    if (consumed == 0) continue;
    auto options =
        parse_options(command.spec, {args.begin() + static_cast<long>(consumed), args.end()});
    if (!options) {
      std::cerr << "facebooth: " << options.error().message << "\n";
      return kExitUsage;
    }
    if (options->help_requested) {
      std::cout << format_help(command.spec);
      return kExitOk;
    }
    return command.run(*options);
  }
  std::cerr << "usage: facebooth-track eval track|bench track|track [options] (--help)\n";
  return kExitUsage;
}
