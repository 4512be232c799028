// The facebooth CLI's command table. Each group lives in its own file and contributes
// its commands here; main.cpp only dispatches.
#pragma once

#include <functional>
#include <vector>

#include "host/cli/command_line.hpp"

namespace fb::cli {

// Exit codes shared by every command.
inline constexpr int kExitOk = 0;
inline constexpr int kExitFailure = 1;  // the work could not be done (message on stderr)
inline constexpr int kExitUsage = 2;    // the command line was wrong

struct Command {
  CommandSpec spec;
  std::function<int(const ParsedOptions&)> run;
};

std::vector<Command> camera_commands();
std::vector<Command> bench_commands();
std::vector<Command> fusion_commands();
std::vector<Command> fit_commands();
std::vector<Command> tracking_commands();
std::vector<Command> storage_commands();
std::vector<Command> daemon_commands();
std::vector<Command> rig_commands();
std::vector<Command> self_calibration_commands();
std::vector<Command> camera_calibrate_commands();  // camera_calibrate.cpp
std::vector<Command> calibration_eval_commands();  // calibration_eval.cpp
std::vector<Command> texture_commands();           // texture_commands.cpp
std::vector<Command> texture_eval_commands();      // texture_eval.cpp

// Prints "facebooth: <message>" to stderr and returns kExitFailure.
int report_failure(const Error& error);

}  // namespace fb::cli
