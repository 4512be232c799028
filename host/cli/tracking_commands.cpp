// facebooth tracking commands (filled in by the tracking work).
#include "host/cli/commands.hpp"

namespace fb::cli {
std::vector<Command> tracking_commands() { return {}; }
}  // namespace fb::cli
