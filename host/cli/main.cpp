// facebooth: the companion host tool and the device's command-line front end.
#include <iostream>
#include <string>
#include <vector>

#include "host/cli/commands.hpp"

namespace fb::cli {

int report_failure(const Error& error) {
  std::cerr << "facebooth: " << error.message << "\n";
  return kExitFailure;
}

namespace {

std::vector<Command> all_commands() {
  std::vector<Command> commands;
  for (auto group :
       {camera_commands(), bench_commands(), fusion_commands(), fit_commands(), tracking_commands(),
        storage_commands(), daemon_commands(), rig_commands(), self_calibration_commands(),
        camera_calibrate_commands(), calibration_eval_commands(), texture_commands(),
        texture_eval_commands()}) {
    for (auto& command : group) commands.push_back(std::move(command));
  }
  return commands;
}

void print_overview(std::ostream& out, const std::vector<Command>& commands) {
  out << "usage: facebooth <command> [options]\n\n"
         "facebooth drives a Kinect v1 face-capture appliance and does the host-side work.\n\n"
         "commands:\n";
  for (const auto& command : commands) {
    std::string left = "  " + command.spec.path;
    out << left << std::string(left.size() < 26 ? 26 - left.size() : 1, ' ') << command.spec.summary
        << "\n";
  }
  out << "\n'facebooth <command> --help' describes a command's options.\n";
}

}  // namespace
}  // namespace fb::cli

int main(int argc, char** argv) {
  using namespace fb::cli;
  const std::vector<std::string> args(argv + 1, argv + argc);
  const auto commands = all_commands();
  if (args.empty() || args[0] == "-h" || args[0] == "--help" || args[0] == "help") {
    print_overview(args.empty() ? std::cerr : std::cout, commands);
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
    std::cerr << "facebooth: unknown command '" << args[0] << (args.size() > 1 ? " " + args[1] : "")
              << "'\n\n";
    print_overview(std::cerr, commands);
    return kExitUsage;
  }
  const std::vector<std::string> rest(args.begin() + static_cast<long>(consumed), args.end());
  auto options = parse_options(chosen->spec, rest);
  if (!options) {
    std::cerr << "facebooth: " << options.error().message << "\n";
    return kExitUsage;
  }
  if (options->help_requested) {
    std::cout << format_help(chosen->spec);
    return kExitOk;
  }
  try {
    return chosen->run(*options);
  } catch (const std::exception& e) {
    // Third-party exceptions that escaped a module boundary are bugs; still say what happened.
    std::cerr << "facebooth: internal error: " << e.what() << "\n";
    return kExitFailure;
  }
}
