// facebooth storage commands (filled in by the storage work).
#include "host/cli/commands.hpp"

namespace fb::cli {
std::vector<Command> storage_commands() { return {}; }
}  // namespace fb::cli
