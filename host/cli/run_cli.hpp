// The dispatcher both command-line binaries share: `facebooth` (the product's commands) and
// `facebooth-lab` (sim/lab: eval and bench). Each main() builds its command table and calls this.
#pragma once

#include <string_view>
#include <vector>

#include "host/cli/commands.hpp"

namespace fb::cli {

// Parses argv against `commands` (one or two words, the longest match wins), prints the
// overview or a command's --help, and runs the chosen command. `program` and `blurb` head the
// overview ("usage: <program> <command> [options]").
int run_cli(std::string_view program, std::string_view blurb, const std::vector<Command>& commands,
            int argc, char** argv);

}  // namespace fb::cli
