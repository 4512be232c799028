// The tracking commands' entries in the command table, one file each: eval track
// (track_eval.cpp), bench track (track_bench.cpp); tracking_commands.cpp adds `track` and
// lists all three.
#pragma once

#include "host/cli/commands.hpp"

namespace fb::cli {

Command eval_track_command();
Command bench_track_command();

}  // namespace fb::cli
