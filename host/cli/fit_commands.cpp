// facebooth fit commands (filled in by the fit work).
#include "host/cli/commands.hpp"

namespace fb::cli {
std::vector<Command> fit_commands() { return {}; }
}  // namespace fb::cli
