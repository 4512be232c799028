#include "host/cli/run_cli.hpp"

#include <iostream>
#include <string>

namespace fb::cli {
namespace {

void print_overview(std::ostream& out, std::string_view program, std::string_view blurb,
                    const std::vector<Command>& commands) {
  out << "usage: " << program << " <command> [options]\n\n" << blurb << "\n\ncommands:\n";
  for (const auto& command : commands) {
    std::string left = "  " + command.spec.path;
    out << left << std::string(left.size() < 26 ? 26 - left.size() : 1, ' ') << command.spec.summary
        << "\n";
  }
  out << "\n'" << program << " <command> --help' describes a command's options.\n";
}

}  // namespace

int run_cli(std::string_view program, std::string_view blurb, const std::vector<Command>& commands,
            int argc, char** argv) {
  const std::vector<std::string> args(argv + 1, argv + argc);
  if (args.empty() || args[0] == "-h" || args[0] == "--help" || args[0] == "help") {
    print_overview(args.empty() ? std::cerr : std::cout, program, blurb, commands);
    return args.empty() ? kExitUsage : kExitOk;
  }
  // Commands are one or two words ("camera list"); match the longest.
  const Command* chosen = nullptr;
  std::size_t consumed = 0;
  for (const auto& command : commands) {
    const std::string& path = command.spec.path;
    const auto space = path.find(' ');
    if (space == std::string::npos) {
      if (args[0] == path && consumed < 1) chosen = &command, consumed = 1;
    } else if (args.size() >= 2 && args[0] == path.substr(0, space) &&
               args[1] == path.substr(space + 1)) {
      chosen = &command, consumed = 2;
    }
  }
  if (chosen == nullptr) {
    std::cerr << program << ": unknown command '" << args[0]
              << (args.size() > 1 ? " " + args[1] : "") << "'\n\n";
    print_overview(std::cerr, program, blurb, commands);
    return kExitUsage;
  }
  const std::vector<std::string> rest(args.begin() + static_cast<long>(consumed), args.end());
  auto options = parse_options(chosen->spec, rest, program);
  if (!options) {
    std::cerr << program << ": " << options.error().message << "\n";
    return kExitUsage;
  }
  if (options->help_requested) {
    std::cout << format_help(chosen->spec, program);
    return kExitOk;
  }
  try {
    return chosen->run(*options);
  } catch (const std::exception& e) {
    // Third-party exceptions that escaped a module boundary are bugs; still say what happened.
    std::cerr << program << ": internal error: " << e.what() << "\n";
    return kExitFailure;
  }
}

}  // namespace fb::cli
