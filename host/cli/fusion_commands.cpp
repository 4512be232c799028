// facebooth eval fusion | bench fusion (filled in by the fusion work).
#include "host/cli/commands.hpp"

namespace fb::cli {
std::vector<Command> fusion_commands() { return {}; }
}  // namespace fb::cli
